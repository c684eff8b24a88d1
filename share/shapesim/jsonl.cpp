#include "shapesim/jsonl.hpp"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iostream>
#include <limits>

namespace shapesim {

namespace {

// nlohmann's what() is "[json.exception.parse_error.101] parse error at line 1, column 7:
// syntax error while parsing value - invalid literal; last read: '...'". Keep "column 7: …":
// the line number is ours, the tag is noise.
// A whole document keeps nlohmann's "line 3, column 7" (`from` = "line ").
std::string parse_message(const nlohmann::json::exception& e, const char* from = "column ") {
    std::string text = e.what();
    if (const auto at = text.find(from); at != std::string::npos)
        return "invalid JSON at " + text.substr(at);
    if (const auto tag_end = text.find("] "); tag_end != std::string::npos)
        text = text.substr(tag_end + 2);
    return "invalid JSON: " + text;
}

bool is_blank(const std::string& s) { return s.find_first_not_of(" \t\r\n") == std::string::npos; }

// A short rendering of a value for messages: `string "abc"`, `null`, `array`.
// (A structured value is never dumped: the dump recurses, and a line of 10⁵ nested brackets
// would overflow the stack.)
std::string describe(const Json& value) {
    if (value.is_structured()) return value.type_name();
    std::string text = value.dump();
    if (text.size() > 40) text = text.substr(0, 37) + "...";
    return std::string(value.type_name()) + " " + text;
}

std::string join(const std::vector<std::string>& items) {
    std::string out;
    for (const auto& s : items) out += (out.empty() ? "\"" : " or \"") + s + "\"";
    return out;
}

// The dotted path of the first non-finite number in `value`, or "" when there is none.
std::string non_finite_path(const Json& value, const std::string& path) {
    if (value.is_number_float()) return std::isfinite(value.get<double>()) ? "" : path;
    if (value.is_object()) {
        for (const auto& [key, item] : value.items()) {
            auto found = non_finite_path(item, path.empty() ? key : path + "." + key);
            if (!found.empty()) return found;
        }
    } else if (value.is_array()) {
        for (std::size_t k = 0; k < value.size(); ++k) {
            auto found = non_finite_path(value[k], path + "[" + std::to_string(k) + "]");
            if (!found.empty()) return found;
        }
    }
    return "";
}

// A fast strict parser for the common line: the DOM nlohmann would build, about three times
// faster (numbers by std::from_chars, no per-character input adapter). It declines — and
// nlohmann parses the line, with its own error messages — whenever the text strays from plain
// JSON it can match exactly: non-ASCII bytes or \u escapes in strings, integers beyond 64 bits,
// numbers out of double range, duplicate keys, nesting deeper than 64, any syntax error.
// Integers stay integers as nlohmann keeps them (unsigned without a sign, signed with one).
class FastJson {
public:
    FastJson(std::string_view text, NumberPairs* pairs)
        : p_(text.data()), end_(text.data() + text.size()), pairs_(pairs) {
        if (pairs_) {
            pairs_->found = false;
            pairs_->values.clear();
        }
    }
    std::optional<Json> document() {
        Json out;
        space();
        if (!value(out, 0)) return std::nullopt;
        space();
        if (p_ != end_) return std::nullopt;
        return out;
    }

private:
    void space() {
        while (p_ < end_ && (*p_ == ' ' || *p_ == '\t' || *p_ == '\n' || *p_ == '\r')) ++p_;
    }
    bool take(char c) {
        if (p_ == end_ || *p_ != c) return false;
        ++p_;
        return true;
    }
    bool literal(std::string_view word) {
        if (std::size_t(end_ - p_) < word.size() || std::memcmp(p_, word.data(), word.size()) != 0)
            return false;
        p_ += word.size();
        return true;
    }
    bool value(Json& out, int depth) {
        if (p_ == end_ || depth > 64) return false;
        switch (*p_) {
        case '{': return object(out, depth);
        case '[': return array(out, depth);
        case '"': {
            std::string text;
            if (!string(text)) return false;
            out = std::move(text);
            return true;
        }
        case 't': return literal("true") && (out = true, true);
        case 'f': return literal("false") && (out = false, true);
        case 'n': return literal("null") && (out = nullptr, true);
        default: return number(out);
        }
    }
    bool string(std::string& out) {
        if (!take('"')) return false;
        for (;;) {
            const char* run = p_;
            while (p_ < end_ && *p_ != '"' && *p_ != '\\' && (unsigned char)(*p_) >= 0x20 &&
                   (unsigned char)(*p_) < 0x80)
                ++p_;
            out.append(run, p_);
            if (p_ == end_) return false;
            if (*p_ == '"') {
                ++p_;
                return true;
            }
            if (*p_ != '\\' || ++p_ == end_) return false;  // a control or non-ASCII byte
            static constexpr std::string_view from = "\"\\/bfnrt", to = "\"\\/\b\f\n\r\t";
            const auto k = from.find(*p_++);
            if (k == std::string_view::npos) return false;  // \u…: nlohmann's
            out += to[k];
        }
    }
    static bool digit(char c) { return c >= '0' && c <= '9'; }
    // A number as the DOM holds it (Json), or as as_double reads that (double).
    template <class Out>
    bool number(Out& out) {
        const char* start = p_;
        const bool negative = take('-');
        if (p_ == end_ || !digit(*p_)) return false;
        if (*p_ == '0')
            ++p_;
        else
            while (p_ < end_ && digit(*p_)) ++p_;
        bool integral = true;
        if (p_ < end_ && *p_ == '.') {
            ++p_;
            if (p_ == end_ || !digit(*p_)) return false;
            while (p_ < end_ && digit(*p_)) ++p_;
            integral = false;
        }
        if (p_ < end_ && (*p_ == 'e' || *p_ == 'E')) {
            ++p_;
            if (p_ < end_ && (*p_ == '+' || *p_ == '-')) ++p_;
            if (p_ == end_ || !digit(*p_)) return false;
            while (p_ < end_ && digit(*p_)) ++p_;
            integral = false;
        }
        if (integral && negative) {
            std::int64_t v;
            const auto r = std::from_chars(start, p_, v);
            if (r.ec != std::errc() || r.ptr != p_) return false;
            out = Out(v);
        } else if (integral) {
            std::uint64_t v;
            const auto r = std::from_chars(start, p_, v);
            if (r.ec != std::errc() || r.ptr != p_) return false;
            out = Out(v);
        } else {
            double v;
            const auto r = std::from_chars(start, p_, v);
            if (r.ec != std::errc() || r.ptr != p_ || !std::isfinite(v)) return false;
            out = v;
        }
        return true;
    }
    bool object(Json& out, int depth) {
        ++p_;  // '{'
        out = Json::object();
        auto& members = out.get_ref<Json::object_t&>();
        space();
        if (take('}')) return true;
        // A member's key is const, so a growing vector copies the members (values and all)
        // instead of moving them: room for a record's fields up front.
        members.reserve(depth == 0 ? 32 : 4);
        for (;;) {
            std::string key;
            if (!string(key)) return false;
            space();
            if (!take(':')) return false;
            space();
            for (const auto& member : members)
                if (member.first == key) return false;  // a duplicate: nlohmann's rule
            if (depth == 0 && pairs_ && key == pairs_->key) {
                if (pairs_->found || !number_pairs()) return false;
                pairs_->found = true;
            } else {
                Json item;
                if (!value(item, depth + 1)) return false;
                members.emplace_back(std::move(key), std::move(item));
            }
            space();
            if (take('}')) return true;
            if (!take(',')) return false;
            space();
        }
    }
    bool array(Json& out, int depth) {
        ++p_;  // '['
        out = Json::array();
        auto& items = out.get_ref<Json::array_t&>();
        space();
        if (take(']')) return true;
        for (;;) {
            Json item;
            if (!value(item, depth + 1)) return false;
            items.push_back(std::move(item));
            space();
            if (take(']')) return true;
            if (!take(',')) return false;
            space();
        }
    }

    // [[a, b], …] straight into pairs_->values; anything else declines.
    bool number_pairs() {
        if (!take('[')) return false;
        space();
        if (take(']')) return true;
        for (;;) {
            double a, b;
            if (!take('[')) return false;
            space();
            if (!number(a)) return false;
            space();
            if (!take(',')) return false;
            space();
            if (!number(b)) return false;
            space();
            if (!take(']')) return false;
            pairs_->values.emplace_back(a, b);
            space();
            if (take(']')) return true;
            if (!take(',')) return false;
            space();
        }
    }

    const char* p_;
    const char* end_;
    NumberPairs* pairs_;
};

}  // namespace

std::optional<Json> parse_json_fast(std::string_view text, NumberPairs* pairs) {
    return FastJson(text, pairs).document();
}

// ---------------------------------------------------------------------------------- reader

Json parse_json_document(const std::string& text, const std::string& name) {
    if (auto fast = parse_json_fast(text)) return std::move(*fast);
    try {
        return Json::parse(text);
    } catch (const nlohmann::json::exception& e) {
        throw Error(parse_message(e, "line "), name);
    }
}

JsonlReader::JsonlReader(const std::string& name, std::vector<std::string> schemas)
    : in_(&std::cin), name_(name), schemas_(std::move(schemas)) {
    if (name == "-") return;
    auto file = std::make_unique<std::ifstream>(name, std::ios::in | std::ios::binary);
    if (!*file) throw Error(std::string("cannot open: ") + std::strerror(errno), name);
    owned_ = std::move(file);
    in_ = owned_.get();
}

JsonlReader::JsonlReader(std::istream& in, std::string name, std::vector<std::string> schemas)
    : in_(&in), name_(std::move(name)), schemas_(std::move(schemas)) {}

JsonlReader::~JsonlReader() = default;

bool JsonlReader::next_line(std::string& text) {
    // Skip blank lines; every line, blank or not, counts for the line number.
    do {
        if (!read_text_line(*in_, text, name_, line_ + 1, "a JSON-lines catalogue"))
            return false;
        ++line_;
    } while (is_blank(text));
    return true;
}

Json JsonlReader::parse_line(const std::string& text, long line, NumberPairs* pairs) const {
    Json record;
    try {
        if (auto fast = parse_json_fast(text, pairs)) {
            record = std::move(*fast);
        } else {
            if (pairs) pairs->found = false;  // the DOM holds them
            record = Json::parse(text);
        }
    } catch (const nlohmann::json::exception& e) {
        throw Error(parse_message(e), name_, line);
    }
    if (!record.is_object())
        throw Error("expected a JSON object, got " + describe(record), name_, line);

    // The schema gate: a program refuses the wrong stream on its first line.
    const auto schema = record.find("schema");
    if (schema == record.end())
        throw Error("missing" + (schemas_.empty() ? "" : " (expected " + join(schemas_) + ")"),
                    name_, line, "schema");
    if (!schema->is_string())
        throw Error("expected a string, got " + describe(*schema), name_, line, "schema");
    if (!schemas_.empty()) {
        const std::string& s = schema->get_ref<const std::string&>();
        bool ok = false;
        for (const auto& accepted : schemas_) ok = ok || s == accepted;
        if (!ok)
            throw Error("expected " + join(schemas_) + ", got \"" + s + "\"", name_, line,
                        "schema");
    }
    return record;
}

bool JsonlReader::next(Json& record) {
    if (!next_line(text_)) return false;
    record = parse_line(text_, line_);
    return true;
}

// ---------------------------------------------------------------------------------- writer

JsonlWriter::JsonlWriter(std::ostream& out, std::string name) : out_(out), name_(std::move(name)) {}

void JsonlWriter::write(const Json& record) {
    const long line = count_ + 1;
    if (!record.is_object())
        throw Error("a JSON-lines record must be an object, got " + describe(record), name_, line);
    if (const auto path = non_finite_path(record, ""); !path.empty())
        throw Error("is NaN or infinite, which JSON cannot hold", name_, line, path);
    std::string text;
    try {
        text = record.dump();  // strict UTF-8: invalid bytes throw rather than pass through
    } catch (const nlohmann::json::exception& e) {
        throw Error(std::string("cannot write: ") + e.what(), name_, line);
    }
    text += '\n';
    errno = 0;
    out_.write(text.data(), std::streamsize(text.size()));
    out_.flush();  // stream: the next program in the pipe sees each record at once
    if (!out_) {
        const int err = errno;
        throw Error(
            std::string("write failed") + (err ? ": " + std::string(std::strerror(err)) : ""),
            name_);
    }
    ++count_;
}

// -------------------------------------------------------------------------------- accessors

double as_double(const Json& value, const std::string& field) {
    if (!value.is_number()) throw Error("expected a number, got " + describe(value), {}, 0, field);
    const double x = value.get<double>();
    if (!std::isfinite(x)) throw Error("must be finite", {}, 0, field);
    return x;
}

int as_int(const Json& value, const std::string& field) {
    if (value.is_number_integer()) {
        if (value.is_number_unsigned()) {
            const auto u = value.get<std::uint64_t>();
            if (u <= std::uint64_t(std::numeric_limits<int>::max())) return int(u);
        } else {
            const auto i = value.get<std::int64_t>();
            if (i >= std::numeric_limits<int>::min() && i <= std::numeric_limits<int>::max())
                return int(i);
        }
        throw Error("integer out of range, got " + value.dump(), {}, 0, field);
    }
    if (value.is_number_float()) {
        const double x = value.get<double>();
        if (std::isfinite(x) && x == std::floor(x) && std::abs(x) <= 2147483647.0) return int(x);
    }
    throw Error("expected an integer, got " + describe(value), {}, 0, field);
}

std::string as_string(const Json& value, const std::string& field) {
    if (!value.is_string()) throw Error("expected a string, got " + describe(value), {}, 0, field);
    return value.get<std::string>();
}

namespace {
// The member `field` of `object`; nullptr when absent or null.
const Json* member(const Json& object, const std::string& field) {
    if (!object.is_object()) throw Error("expected a JSON object, got " + describe(object));
    const auto it = object.find(field);
    return it == object.end() || it->is_null() ? nullptr : &*it;
}
const Json& required_member(const Json& object, const std::string& field) {
    const Json* value = member(object, field);
    if (!value) throw Error("missing", {}, 0, field);
    return *value;
}
}  // namespace

double required_double(const Json& object, const std::string& field) {
    return as_double(required_member(object, field), field);
}
std::optional<double> optional_double(const Json& object, const std::string& field) {
    const Json* value = member(object, field);
    return value ? std::optional<double>(as_double(*value, field)) : std::nullopt;
}
int required_int(const Json& object, const std::string& field) {
    return as_int(required_member(object, field), field);
}
std::optional<int> optional_int(const Json& object, const std::string& field) {
    const Json* value = member(object, field);
    return value ? std::optional<int>(as_int(*value, field)) : std::nullopt;
}
std::string required_string(const Json& object, const std::string& field) {
    return as_string(required_member(object, field), field);
}
std::optional<std::string> optional_string(const Json& object, const std::string& field) {
    const Json* value = member(object, field);
    return value ? std::optional<std::string>(as_string(*value, field)) : std::nullopt;
}
const Json& required_array(const Json& object, const std::string& field) {
    const Json& value = required_member(object, field);
    if (!value.is_array()) throw Error("expected an array, got " + describe(value), {}, 0, field);
    return value;
}
const Json* optional_array(const Json& object, const std::string& field) {
    const Json* value = member(object, field);
    if (value && !value->is_array())
        throw Error("expected an array, got " + describe(*value), {}, 0, field);
    return value;
}
const Json& required_object(const Json& object, const std::string& field) {
    const Json& value = required_member(object, field);
    if (!value.is_object()) throw Error("expected an object, got " + describe(value), {}, 0, field);
    return value;
}
std::vector<std::string> optional_strings(const Json& object, const std::string& field) {
    std::vector<std::string> out;
    if (const Json* list = optional_array(object, field))
        for (std::size_t k = 0; k < list->size(); ++k)
            out.push_back(as_string((*list)[k], field + "[" + std::to_string(k) + "]"));
    return out;
}

}  // namespace shapesim
