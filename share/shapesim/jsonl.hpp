// JSON-lines catalogues (DESIGN §2): one JSON object per line, UTF-8, no header line, every
// record carrying a "schema" string such as "shapesim.source/1". JsonlReader reads line by
// line ("-" is stdin), checks each schema and reports errors as file:line: field: message;
// JsonlWriter writes shortest round-trip doubles, flushes every line, and refuses NaN/Inf and
// failed streams with an Error. Records are ordered_json: "schema" and "id" lead, unknown
// fields pass through in order.
// Details: docs/algorithms.md#json-lines-catalogues
#pragma once

#include "shapesim/error.hpp"
#include "shapesim/parallel.hpp"
#include "shapesim/text_rows.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <complex>
#include <functional>
#include <iosfwd>
#include <iterator>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace shapesim {

/// A JSON value with insertion-ordered objects.
using Json = nlohmann::ordered_json;

/// Parse `text` as one JSON document (a morphology model); Error naming `name` with the line
/// and column of a syntax error, e.g. `model.json: invalid JSON at line 3, column 7: …`.
Json parse_json_document(const std::string& text, const std::string& name);

/// A top-level member read straight into numbers rather than into the DOM (a record's shapelet
/// coefficients: most of a line, and a DOM node each): `key`'s [[a, b], …] as (a, b) pairs, each
/// number as as_double reads it from the DOM.
struct NumberPairs {
    std::string key;
    std::vector<std::complex<double>> values;
    bool found = false;  ///< the member was there, and read into `values` (not into the DOM)
};

/// `text` parsed as one JSON value by a fast strict parser, or nothing where it declines (any
/// syntax error, and the rarer corners it leaves to nlohmann: non-ASCII or \u escapes in
/// strings, integers past 64 bits, numbers past double range, duplicate keys, deep nesting).
/// What it returns is what Json::parse returns, integers as integers (tested). With `pairs`,
/// a top-level member named pairs->key is read into it instead (and declined unless it is an
/// array of two-number arrays).
std::optional<Json> parse_json_fast(std::string_view text, NumberPairs* pairs = nullptr);

/// Whether Record reads a member as NumberPairs: a `pairs_key` and from_json(Json, NumberPairs).
template <class Record, class = void>
struct has_pairs_key : std::false_type {};
template <class Record>
struct has_pairs_key<Record, std::void_t<decltype(Record::pairs_key)>> : std::true_type {};

/// Reads a JSON-lines stream, one object per line, checking each record's schema.
class JsonlReader {
public:
    /// Open `name` ("-" = stdin). `schemas` lists the accepted values of "schema"; empty
    /// accepts any string. Throws Error when the file cannot be opened.
    JsonlReader(const std::string& name, std::vector<std::string> schemas);
    /// Read from an existing stream; `name` is used in messages.
    JsonlReader(std::istream& in, std::string name, std::vector<std::string> schemas);
    ~JsonlReader();

    /// The next record into `record`; false at the end of input. Throws Error(file, line)
    /// for malformed JSON, a non-object line, a missing or unexpected schema, a read error.
    bool next(Json& record);

    /// The next record converted by `Record::from_json(const Json&)`; errors it throws get
    /// this reader's file and line.
    template <class Record>
    bool next_record(Record& out) {
        Json record;
        if (!next(record)) return false;
        try {
            out = Record::from_json(record);
        } catch (const Error& e) {
            throw locate(e);
        }
        return true;
    }

    /// Every remaining record converted by `Record::from_json`, parsed on `threads` threads
    /// (lines are read in order, each parsed alone; the error of the first bad line in line
    /// order is thrown, as next_record would). `lines`, when given, gets each record's line.
    /// `each`, when given, is called on every record as it is made (on the parsing thread; it
    /// may drop what its caller will not use). Lines are held a chunk at a time (chunk_lines),
    /// not the whole input, so the memory is the records' own.
    template <class Record>
    std::vector<Record> read_all(int threads, std::vector<long>* lines = nullptr,
                                 const std::function<void(Record&)>& each = {}) {
        // Chunks of records, joined at the end into one vector of exactly their count, each
        // chunk freed as it is moved: no doubling of a growing vector (a million records'
        // worth of it).
        std::vector<std::vector<Record>> chunks;
        std::vector<long> all_lines;
        std::vector<std::string> texts;
        std::vector<long> at;
        std::string text;
        bool more = true;
        while (more) {
            texts.clear();
            at.clear();
            while (texts.size() < chunk_lines && (more = next_line(text))) {
                texts.push_back(std::move(text));
                at.push_back(line_);
            }
            if (texts.empty()) break;
            std::vector<Record>& chunk = chunks.emplace_back(texts.size());
            std::vector<std::optional<Error>> errors(texts.size());
            parallel_for(texts.size(), threads, [&](std::size_t k, int) {
                try {
                    if constexpr (has_pairs_key<Record>::value) {
                        // The record's number pairs read straight (Record::from_json(json, pairs)).
                        NumberPairs pairs{Record::pairs_key, {}, false};
                        const Json record = parse_line(texts[k], at[k], &pairs);
                        chunk[k] = Record::from_json(record, pairs);
                    } else {
                        chunk[k] = Record::from_json(parse_line(texts[k], at[k]));
                    }
                    if (each) each(chunk[k]);
                } catch (const Error& e) {
                    errors[k] = e.at(name_, at[k]);
                } catch (const std::exception& e) {
                    errors[k] = Error(e.what(), name_, at[k]);
                }
            });
            for (auto& error : errors)
                if (error) throw *error;
            all_lines.insert(all_lines.end(), at.begin(), at.end());
        }
        std::vector<Record> records;
        if (chunks.size() == 1) {
            records = std::move(chunks.front());
        } else {
            records.reserve(all_lines.size());
            for (std::vector<Record>& chunk : chunks) {
                std::move(chunk.begin(), chunk.end(), std::back_inserter(records));
                std::vector<Record>().swap(chunk);
            }
        }
        if (lines) *lines = std::move(all_lines);
        return records;
    }
    /// Lines read_all holds at once.
    static constexpr std::size_t chunk_lines = 16384;

    /// `e` placed at the current record (file and line; its field is kept).
    Error locate(const Error& e) const { return e.at(name_, line_); }
    /// File name for messages ("-" for stdin).
    const std::string& name() const { return name_; }
    /// 1-based line of the last record returned (0 before the first).
    long line() const { return line_; }

private:
    bool next_line(std::string& text);  ///< the next non-blank line; false at the end
    /// Parsed, schema checked; with `pairs`, its member read as NumberPairs when it can be.
    Json parse_line(const std::string& text, long line, NumberPairs* pairs = nullptr) const;

    std::unique_ptr<std::istream> owned_;
    std::istream* in_;
    std::string name_;
    std::vector<std::string> schemas_;
    long line_ = 0;
    std::string text_;
};

/// Writes records as JSON lines, one per line, flushed per record.
class JsonlWriter {
public:
    /// @param out  stream to write to (stdout, a file, an AtomicTextFile's stream)
    /// @param name the output's name for messages ("-" for stdout)
    JsonlWriter(std::ostream& out, std::string name);

    /// Write `record` (a JSON object) as one line and flush. Throws Error naming the field
    /// when a number is NaN or infinite (nothing is written), or when the stream fails.
    void write(const Json& record);
    /// Records written so far.
    long count() const { return count_; }

private:
    std::ostream& out_;
    std::string name_;
    long count_ = 0;
};

// Typed field accessors. Each throws Error(message, {}, 0, field) — wrong type, missing,
// non-finite, out of range — for the reader to place (JsonlReader::next_record / locate).
// An optional field that is absent or null reads as nullopt (null is how a schema documents
// "not measured").

/// `value` as a finite number; `field` names it in errors.
double as_double(const Json& value, const std::string& field);
/// `value` as an int (an integral number in int range; 4.0 is accepted as 4).
int as_int(const Json& value, const std::string& field);
/// `value` as a string.
std::string as_string(const Json& value, const std::string& field);

double required_double(const Json& object, const std::string& field);
std::optional<double> optional_double(const Json& object, const std::string& field);
int required_int(const Json& object, const std::string& field);
std::optional<int> optional_int(const Json& object, const std::string& field);
std::string required_string(const Json& object, const std::string& field);
std::optional<std::string> optional_string(const Json& object, const std::string& field);
/// The array at `field`; Error when missing or not an array.
const Json& required_array(const Json& object, const std::string& field);
/// The array at `field`, or nullptr when absent or null.
const Json* optional_array(const Json& object, const std::string& field);
/// The object at `field`; Error when missing or not an object.
const Json& required_object(const Json& object, const std::string& field);
/// A list of strings (e.g. `flags`); empty when absent or null.
std::vector<std::string> optional_strings(const Json& object, const std::string& field);

}  // namespace shapesim
