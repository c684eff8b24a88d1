// A JSON-lines schema as a table of fields (STYLE "JSON-lines"): each entry names a field and
// says how its record holds it (a member, required or optional, a check), so one reader and
// one writer serve every schema. Reading walks the table in order through jsonl.hpp's typed
// accessors (errors name the field) and keeps the fields no entry names in `extra`; writing
// puts "schema", the entries in order, `extra` (the unknown fields, in their order) and last
// the entries placed after it (long coefficient arrays). What a member cannot say (a field
// read by a rule of its own, several fields present together) is a custom entry: a reader and
// a writer. The tables are records.cpp's and noise.cpp's.
#pragma once

#include "shapesim/jsonl.hpp"

#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace shapesim {

/// How a member field is read.
enum class FieldRule {
    required,  ///< present and not null
    optional,  ///< absent or null keeps the member's default; an empty string is not written
    id,        ///< a non-empty string; an integer (a SExtractor NUMBER) reads as its decimal text
};

/// Where a field is written: in the table's order, or after `extra` (so a line's long
/// coefficient arrays come last and its short fields stay readable at its start).
enum class FieldPlace { in_order, after_extra };

template <class Record>
struct Field {
    using Member = std::variant<std::monostate, double Record::*, std::optional<double> Record::*,
                                int Record::*, long Record::*, std::string Record::*,
                                std::optional<std::string> Record::*,
                                std::vector<std::string> Record::*, std::vector<double> Record::*>;
    /// A custom entry's reader: `object` is the record's JSON, `pairs` the member read apart
    /// as number pairs (JsonlReader's fast path) or nullptr.
    using Read = void (*)(Record&, const Json& object, NumberPairs* pairs);
    using Write = void (*)(const Record&, Json& object);
    /// A number's check (`validate`): throws Error naming `field`.
    using Check = void (*)(std::string_view field, double value);

    std::string_view name;
    Member member;  ///< monostate: a custom entry, or a name only
    FieldRule rule = FieldRule::required;
    Check check = nullptr;  ///< for double and optional<double> members (an absent one passes)
    Read read = nullptr;    ///< custom entries: either may be nullptr
    Write write = nullptr;
    FieldPlace place = FieldPlace::in_order;

    /// A member, read by its type: optional<…> and a list of strings may be absent (a list is
    /// written even when empty, an optional only when it holds a value).
    Field(std::string_view name, Member member, Check check = nullptr)
        : name(name), member(member), check(check) {}
    Field(std::string_view name, Member member, FieldRule rule, Check check = nullptr)
        : name(name), member(member), rule(rule), check(check) {}
    /// A custom entry.
    Field(std::string_view name, Read read, Write write, FieldPlace place = FieldPlace::in_order)
        : name(name), read(read), write(write), place(place) {}
    /// A name only: a field read and written by a custom entry before it (a group of fields
    /// present together), named here so that it is never taken for an unknown one.
    Field(std::string_view name) : name(name) {}
};

template <class Record>
using Fields = std::vector<Field<Record>>;

namespace fields_detail {

void read_value(const Json& j, const std::string& name, FieldRule, double& v);
void read_value(const Json& j, const std::string& name, FieldRule, std::optional<double>& v);
void read_value(const Json& j, const std::string& name, FieldRule, int& v);
void read_value(const Json& j, const std::string& name, FieldRule, long& v);
void read_value(const Json& j, const std::string& name, FieldRule, std::string& v);
void read_value(const Json& j, const std::string& name, FieldRule, std::optional<std::string>& v);
void read_value(const Json& j, const std::string& name, FieldRule, std::vector<std::string>& v);
void read_value(const Json& j, const std::string& name, FieldRule, std::vector<double>& v);

void write_value(Json& j, const std::string& name, FieldRule, double v);
void write_value(Json& j, const std::string& name, FieldRule, const std::optional<double>& v);
void write_value(Json& j, const std::string& name, FieldRule, int v);
void write_value(Json& j, const std::string& name, FieldRule, long v);
void write_value(Json& j, const std::string& name, FieldRule, const std::string& v);
void write_value(Json& j, const std::string& name, FieldRule, const std::optional<std::string>& v);
void write_value(Json& j, const std::string& name, FieldRule, const std::vector<std::string>& v);
void write_value(Json& j, const std::string& name, FieldRule, const std::vector<double>& v);

// `action(member)` for a member entry (nothing for a custom or name-only one).
template <class Record, class Action>
void on_member(const Field<Record>& f, Action&& action) {
    std::visit(
        [&](auto member) {
            if constexpr (!std::is_same_v<decltype(member), std::monostate>) action(member);
        },
        f.member);
}

template <class Record>
bool known(const Fields<Record>& fields, std::string_view key) {
    if (key == "schema") return true;
    for (const Field<Record>& f : fields)
        if (key == f.name) return true;
    return false;
}

}  // namespace fields_detail

/// Throws Error (field "schema") unless `object`'s "schema" is `expected`. Top-level lines are
/// checked by JsonlReader already; this is for nested records and direct calls.
void check_schema(const Json& object, const char* expected);

/// Read every entry of `fields` from `object` into `record`, in the table's order.
template <class Record>
void read_fields(const Fields<Record>& fields, const Json& object, Record& record,
                 NumberPairs* pairs = nullptr) {
    for (const Field<Record>& f : fields) {
        if (f.read) f.read(record, object, pairs);
        fields_detail::on_member(f, [&](auto member) {
            fields_detail::read_value(object, std::string(f.name), f.rule, record.*member);
        });
    }
}

/// The fields of `object` no entry names (nor "schema"), in their order.
template <class Record>
Json unknown_fields(const Fields<Record>& fields, const Json& object) {
    Json extra = Json::object();
    for (const auto& [key, value] : object.items())
        if (!fields_detail::known(fields, key)) extra[key] = value;
    return extra;
}

/// Write `record`'s entries into `object`: those in order, then `extra`'s fields that no
/// entry names (when `extra` is given), then those placed after it.
template <class Record>
void write_fields(const Fields<Record>& fields, const Record& record, Json& object,
                  const Json* extra = nullptr) {
    const auto write = [&](FieldPlace place) {
        for (const Field<Record>& f : fields) {
            if (f.place != place) continue;
            if (f.write) f.write(record, object);
            fields_detail::on_member(f, [&](auto member) {
                fields_detail::write_value(object, std::string(f.name), f.rule, record.*member);
            });
        }
    };
    write(FieldPlace::in_order);
    if (extra)
        for (const auto& [key, value] : extra->items())
            if (!fields_detail::known(fields, key)) object[key] = value;
    write(FieldPlace::after_extra);
}

/// Run every entry's check on `record` in the table's order (an id: not empty).
template <class Record>
void check_fields(const Fields<Record>& fields, const Record& record) {
    for (const Field<Record>& f : fields) {
        if (f.rule == FieldRule::id) {
            if (const auto* m = std::get_if<std::string Record::*>(&f.member);
                m && (record.*(*m)).empty())
                throw Error("must not be empty", {}, 0, std::string(f.name));
        }
        if (!f.check) continue;
        if (const auto* m = std::get_if<double Record::*>(&f.member)) f.check(f.name, record.*(*m));
        if (const auto* m = std::get_if<std::optional<double> Record::*>(&f.member))
            if (const std::optional<double>& v = record.*(*m)) f.check(f.name, *v);
    }
}

/// A record of a schema (`Record::schema`, `Record::extra`): its schema checked, its fields
/// read, the unknown ones kept in `extra`.
template <class Record>
Record read_record(const Fields<Record>& fields, const Json& object, NumberPairs* pairs = nullptr) {
    check_schema(object, Record::schema);
    Record record;
    read_fields(fields, object, record, pairs);
    record.extra = unknown_fields(fields, object);
    return record;
}

/// "schema" first, then write_fields with the record's `extra`.
template <class Record>
Json write_record(const Fields<Record>& fields, const Record& record) {
    Json object;
    object["schema"] = Record::schema;
    write_fields(fields, record, object, &record.extra);
    return object;
}

/// read_record, then the record's own checks (`validate`).
template <class Record>
Record read_valid_record(const Fields<Record>& fields, const Json& object,
                         NumberPairs* pairs = nullptr) {
    Record record = read_record(fields, object, pairs);
    record.validate();
    return record;
}

/// The record's own checks (`validate`), then write_record.
template <class Record>
Json write_valid_record(const Fields<Record>& fields, const Record& record) {
    record.validate();
    return write_record(fields, record);
}

}  // namespace shapesim
