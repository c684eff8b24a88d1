#include "shapesim/table.hpp"

#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/records.hpp"

#include <algorithm>
#include <fstream>
#include <sstream>

#include <charconv>
#include <cstdint>
#include <cmath>
#include <limits>
#include <map>
#include <ostream>
#include <set>

namespace shapesim {

namespace {

using Type = CatalogueColumn::Type;

class CatalogueBuilder {
public:
    explicit CatalogueBuilder(const std::string& flux_unit) : flux_unit_(flux_unit) {}

    void add(const Json& record) {
        const std::string schema = record.value("schema", std::string());
        if (table_.rows == 0) table_.schema = schema;
        else if (schema != table_.schema)
            throw Error("schema " + schema + " in a table of " + table_.schema +
                        " (one catalogue per table)", {}, 0, "schema");
        for (const auto& [key, value] : record.items())
            if (key != "schema") cell(key, value);
        ++table_.rows;
        for (CatalogueColumn& c : table_.columns) pad(c, table_.rows);
    }

    CatalogueTable finish() {
        for (CatalogueColumn& c : table_.columns)
            if (c.has_null && (c.type == Type::integer || c.type == Type::boolean))
                c.type = Type::real;  // NaN is the null a FITS or ECSV reader knows
        return std::move(table_);
    }

private:
    CatalogueColumn& column(const std::string& name, Type type) {
        const auto it = index_.find(name);
        if (it != index_.end()) return table_.columns[it->second];
        index_[name] = table_.columns.size();
        CatalogueColumn c;
        c.name = name;
        c.unit = field_unit(name, flux_unit_);
        c.type = type;
        table_.columns.push_back(std::move(c));
        pad(table_.columns.back(), table_.rows);  // null in the rows before its first
        return table_.columns.back();
    }

    // Fill the column's cells up to `rows` with nulls (a field a record lacks).
    static void pad(CatalogueColumn& c, long rows) {
        const std::size_t n = std::size_t(rows);
        if (c.type == Type::text) {
            if (c.texts.size() < n) c.has_null = true;
            c.texts.resize(n);
        } else {
            if (c.numbers.size() < n) c.has_null = true;
            c.numbers.resize(n, std::numeric_limits<double>::quiet_NaN());
        }
    }

    void cell(const std::string& name, const Json& value) {
        if (value.is_object()) {
            for (const auto& [key, inner] : value.items()) cell(name + "_" + key, inner);
            return;
        }
        if (value.is_array()) {
            bool texts = !value.empty();
            for (const Json& v : value) texts = texts && v.is_string();
            if (!texts && !value.empty()) {
                if (index_.count(name) == 0 && skipped_.insert(name).second)
                    table_.skipped.push_back(name);
                return;
            }
            std::string joined;
            for (const Json& v : value)
                joined += (joined.empty() ? "" : ",") + v.get<std::string>();
            put_text(name, joined);
            return;
        }
        if (value.is_null()) return;  // left a null by pad()
        if (value.is_string()) {
            put_text(name, value.get<std::string>());
            return;
        }
        const Type type = value.is_boolean() ? Type::boolean
                          : value.is_number_float() ? Type::real : Type::integer;
        CatalogueColumn& c = column(name, type);
        if (c.type == Type::text)
            throw Error("a number in a column of text", {}, 0, name);
        if (c.type != type) {
            if (c.type == Type::boolean || type == Type::boolean)
                throw Error("a " + std::string(type == Type::boolean ? "boolean" : "number") +
                            " in a column of " + (type == Type::boolean ? "numbers" : "booleans"),
                            {}, 0, name);
            c.type = Type::real;  // integer and real: real
        }
        const double v = value.is_boolean() ? double(value.get<bool>()) : value.get<double>();
        constexpr std::int64_t limit = std::int64_t(1) << 53;
        bool exact = true;
        if (value.is_number_unsigned()) {
            exact = value.get<std::uint64_t>() <= std::uint64_t(limit);
        } else if (value.is_number_integer()) {
            const std::int64_t i = value.get<std::int64_t>();
            exact = i >= -limit && i <= limit;
        }
        if (type == Type::integer && !exact)
            throw Error("integer beyond 2^53 cannot be a table cell", {}, 0, name);
        if (c.numbers.size() != std::size_t(table_.rows))
            throw Error("the field appears twice in one record", {}, 0, name);
        c.numbers.push_back(v);
    }

    void put_text(const std::string& name, const std::string& text) {
        CatalogueColumn& c = column(name, Type::text);
        if (c.type != Type::text) {
            // A field that began as numbers and turns to text: an id written as 7, then "7a".
            throw Error("text in a column of numbers", {}, 0, name);
        }
        if (c.texts.size() != std::size_t(table_.rows))
            throw Error("the field appears twice in one record", {}, 0, name);
        c.texts.push_back(text);
    }

    std::string flux_unit_;
    CatalogueTable table_;
    std::map<std::string, std::size_t> index_;
    std::set<std::string> skipped_;
};

std::string number_text(double v) {
    if (std::isnan(v)) return "nan";
    if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
    char buffer[32];
    const auto result = std::to_chars(buffer, buffer + sizeof buffer, v);
    return std::string(buffer, result.ptr);
}

// A text cell as ECSV's space-separated rows read it: quoted (with inner quotes doubled) when
// empty, holding a space, tab or quote, or starting with '#'.
std::string text_cell(const std::string& text) {
    if (!text.empty() && text.find_first_of(" \t\"") == std::string::npos && text[0] != '#')
        return text;
    std::string q = "\"";
    for (char c : text) q += c == '"' ? std::string("\"\"") : std::string(1, c);
    return q + "\"";
}

const char* ecsv_type(Type type) {
    switch (type) {
    case Type::integer: return "int64";
    case Type::real: return "float64";
    case Type::boolean: return "bool";
    case Type::text: return "string";
    }
    return "string";
}

}  // namespace

CatalogueTable read_table(JsonlReader& reader, const std::string& flux_unit) {
    CatalogueBuilder builder(flux_unit);
    Json record;
    while (reader.next(record)) {
        try {
            builder.add(record);
        } catch (const Error& e) {
            throw reader.locate(e);
        }
    }
    return builder.finish();
}

void write_ecsv(std::ostream& out, const CatalogueTable& table) {
    out << "# %ECSV 1.0\n# ---\n# datatype:\n";
    for (const CatalogueColumn& c : table.columns) {
        out << "# - {name: " << c.name;
        if (!c.unit.empty()) out << ", unit: " << c.unit;
        out << ", datatype: " << ecsv_type(c.type) << "}\n";
    }
    out << "# meta:\n#   schema: " << table.schema << "\n# schema: astropy-2.0\n";
    for (std::size_t k = 0; k < table.columns.size(); ++k)
        out << (k ? " " : "") << table.columns[k].name;
    out << '\n';
    for (std::size_t r = 0; r < std::size_t(table.rows); ++r) {
        for (std::size_t k = 0; k < table.columns.size(); ++k) {
            const CatalogueColumn& c = table.columns[k];
            if (k) out << ' ';
            switch (c.type) {
            case Type::text: out << text_cell(c.texts[r]); break;
            case Type::boolean: out << (c.numbers[r] != 0.0 ? "True" : "False"); break;
            case Type::integer: out << static_cast<long long>(c.numbers[r]); break;
            case Type::real: out << number_text(c.numbers[r]); break;
            }
        }
        out << '\n';
    }
}

void write_fits_table(FitsWriter& out, const CatalogueTable& table, const std::string& extname) {
    std::vector<FitsColumn> columns;
    for (const CatalogueColumn& c : table.columns) {
        FitsColumn f{c.name, c.unit, {}};
        switch (c.type) {
        case CatalogueColumn::Type::integer:
            f.cells = std::vector<long long>(c.numbers.begin(), c.numbers.end());
            break;
        case CatalogueColumn::Type::real: f.cells = c.numbers; break;
        case CatalogueColumn::Type::boolean: {
            std::vector<bool> flags;
            for (double x : c.numbers) flags.push_back(x != 0.0);
            f.cells = std::move(flags);
            break;
        }
        case CatalogueColumn::Type::text: f.cells = c.texts; break;
        }
        columns.push_back(std::move(f));
    }
    out.write_table(columns, extname, {{"SCHEMA", table.schema, "shapesim record schema"}});
}

// ---------------------------------------------------------------- read_numeric_columns

namespace {

using Columns = std::map<std::string, std::vector<double>>;

bool ends_with(const std::string& s, const std::string& tail) {
    if (s.size() < tail.size()) return false;
    return std::equal(tail.rbegin(), tail.rend(), s.rbegin(),
                      [](char a, char b) { return std::tolower(a) == std::tolower(b); });
}

// A text cell as a number: empty, "nan", "null" or "NaN" are NaN; anything else must parse whole.
bool cell_number(std::string text, double& v) {
    const auto b = text.find_first_not_of(" \t\r\"");
    const auto e = text.find_last_not_of(" \t\r\"");
    text = b == std::string::npos ? std::string() : text.substr(b, e - b + 1);
    if (text.empty() || text == "nan" || text == "NaN" || text == "null" || text == "--") {
        v = std::numeric_limits<double>::quiet_NaN();
        return true;
    }
    char* end = nullptr;
    v = std::strtod(text.c_str(), &end);
    return end == text.c_str() + text.size();
}

// Pick the wanted columns out of a header's names; Error for a required one missing.
std::map<std::string, std::size_t> wanted_columns(const std::vector<std::string>& names,
                                                  const std::vector<std::string>& required,
                                                  const std::vector<std::string>& optional,
                                                  const std::string& path) {
    std::map<std::string, std::size_t> at;
    auto find = [&](const std::string& n) {
        return std::size_t(std::find(names.begin(), names.end(), n) - names.begin());
    };
    for (const std::string& n : required) {
        const std::size_t k = find(n);
        if (k == names.size()) throw Error("no column " + n, path);
        at[n] = k;
    }
    for (const std::string& n : optional)
        if (const std::size_t k = find(n); k < names.size()) at[n] = k;
    return at;
}

Columns read_fits_columns(const std::string& path, const std::vector<std::string>& required,
                          const std::vector<std::string>& optional, long max_rows) {
    FitsReader fits(path);
    if (path.find('[') == std::string::npos) {
        // The first table HDU holding every required column.
        const std::vector<FitsHduInfo> hdus = fits.list_hdus();
        bool found = false;
        for (std::size_t k = 0; k < hdus.size() && !found; ++k) {
            if (hdus[k].is_image) continue;
            fits.move_to(int(k));
            found = std::all_of(required.begin(), required.end(),
                                [&](const std::string& n) { return fits.has_column(n); });
        }
        if (!found) throw Error("no table holds the columns " + [&] {
            std::string list;
            for (const std::string& n : required) list += (list.empty() ? "" : ", ") + n;
            return list;
        }(), path);
    }
    const long rows = fits.table_rows();
    if (rows > max_rows)
        throw Error("more than " + std::to_string(max_rows) + " rows", fits.place());
    Columns out;
    for (const std::string& n : required) out[n] = fits.read_column(n);
    for (const std::string& n : optional)
        if (fits.has_column(n)) out[n] = fits.read_column(n);
    return out;
}

}  // namespace

std::map<std::string, std::vector<double>> read_numeric_columns(
    const std::string& path, const std::vector<std::string>& required,
    const std::vector<std::string>& optional, long max_rows) {
    const std::string file = path.substr(0, path.find('['));
    for (const char* ext : {".fits", ".fit", ".fts", ".ldac", ".cat.fits"})
        if (ends_with(file, ext)) return read_fits_columns(path, required, optional, max_rows);

    std::ifstream in(path);
    if (!in) throw Error("cannot open the catalogue", path);
    std::string line;
    long number = 0;
    Columns out;
    std::map<std::string, std::size_t> at;
    enum class Format { unknown, jsonl, sextractor, sextractor_rows, csv } format = Format::unknown;
    std::vector<std::string> sextractor_names;
    std::set<std::string> seen;  // JSON lines: the required fields some record holds
    long rows = 0;
    auto begin_rows = [&](const std::vector<std::string>& names) {
        at = wanted_columns(names, required, optional, path);
        for (const auto& [n, k] : at) out[n];
    };
    while (read_text_line(in, line, path, number + 1, "a catalogue")) {
        ++number;
        if (!line.empty() && line.back() == '\r') line.pop_back();
        if (line.find_first_not_of(" \t") == std::string::npos) continue;
        if (format == Format::unknown || format == Format::sextractor) {
            const auto first = line.find_first_not_of(" \t");
            if (line[first] == '{') {
                if (format == Format::sextractor)
                    throw Error("a JSON line after a header", path, number);
                format = Format::jsonl;
                for (const std::string& n : required) out[n];
            } else if (line[first] == '#') {
                // SExtractor ASCII_HEAD: "#   3 X_IMAGE   Object position along x   [pixel]"
                std::istringstream f(line.substr(first + 1));
                long column;
                std::string name;
                if (f >> column >> name && column >= 1 && column < 100000) {
                    format = Format::sextractor;
                    // A vector column (e.g. "#  5 FLUX_APER") spans to the next header's number.
                    while (long(sextractor_names.size()) < column - 1)
                        sextractor_names.push_back(
                            sextractor_names.empty() ? "" : sextractor_names.back() + "+");
                    sextractor_names.push_back(name);
                }
                continue;
            } else if (format == Format::unknown) {
                format = Format::csv;
                std::vector<std::string> names;
                std::istringstream f(line);
                std::string cell;
                while (std::getline(f, cell, ',')) {
                    const auto b = cell.find_first_not_of(" \t\""),
                               e = cell.find_last_not_of(" \t\"");
                    names.push_back(b == std::string::npos ? "" : cell.substr(b, e - b + 1));
                }
                begin_rows(names);
                continue;
            } else {
                begin_rows(sextractor_names);
                format = Format::sextractor_rows;
            }
        }
        if (++rows > max_rows)
            throw Error("more than " + std::to_string(max_rows) + " rows", path, number);
        if (format == Format::jsonl) {
            Json record;
            try {
                record = Json::parse(line);
            } catch (const std::exception&) {
                throw Error("not a JSON object", path, number);
            }
            if (!record.is_object()) throw Error("not a JSON object", path, number);
            for (const std::string& n : required)
                if (record.contains(n)) seen.insert(n);
            for (const std::string& n : optional)
                if (record.contains(n) && out.find(n) == out.end()) {
                    out[n].assign(std::size_t(rows - 1), std::numeric_limits<double>::quiet_NaN());
                }
            for (auto& [n, column] : out) {
                double v = std::numeric_limits<double>::quiet_NaN();
                if (const auto it = record.find(n); it != record.end() && !it->is_null()) {
                    if (!it->is_number()) throw Error("must be a number", path, number, n);
                    v = it->get<double>();
                }
                column.push_back(v);
            }
            continue;
        }
        std::vector<std::string> cells;
        if (format == Format::csv) {
            std::istringstream f(line);
            std::string cell;
            while (std::getline(f, cell, ',')) cells.push_back(cell);
            if (!line.empty() && line.back() == ',') cells.push_back("");
        } else {
            std::istringstream f(line);
            std::string cell;
            while (f >> cell) cells.push_back(cell);
        }
        for (const auto& [n, k] : at) {
            double v;
            if (k >= cells.size())
                throw Error("the row has " + std::to_string(cells.size()) + " cells", path, number,
                            n);
            if (!cell_number(cells[k], v))
                throw Error("not a number: " + cells[k].substr(0, 40), path, number, n);
            out[n].push_back(v);
        }
    }
    if (in.bad()) throw Error("read failed", path);
    if (format == Format::jsonl)
        for (const std::string& n : required)
            if (!seen.count(n)) throw Error("no column " + n + " (no record holds it)", path);
    if (format == Format::sextractor && at.empty() && !required.empty())
        begin_rows(sextractor_names);  // a header and no rows
    if (format == Format::unknown)
        for (const std::string& n : required) out[n];  // an empty file: no rows
    return out;
}

}  // namespace shapesim
