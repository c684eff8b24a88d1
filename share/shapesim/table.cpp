#include "shapesim/table.hpp"

#include "shapesim/error.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/records.hpp"

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
            for (const Json& v : value) joined += (joined.empty() ? "" : ",") + v.get<std::string>();
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

}  // namespace shapesim
