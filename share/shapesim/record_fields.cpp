#include "shapesim/record_fields.hpp"

namespace shapesim {

void check_schema(const Json& object, const char* expected) {
    const std::string s = required_string(object, "schema");
    if (s != expected)
        throw Error(std::string("expected \"") + expected + "\", got \"" + s + "\"", {}, 0,
                    "schema");
}

namespace fields_detail {

namespace {
// Ids are strings; an integer id (e.g. from a SExtractor-numbered catalogue) is read as its
// decimal text.
std::string read_id(const Json& j, const std::string& field) {
    const auto it = j.find(field);
    if (it != j.end() && it->is_number_integer()) return it->dump();
    std::string id = required_string(j, field);
    if (id.empty()) throw Error("must not be empty", {}, 0, field);
    return id;
}
}  // namespace

void read_value(const Json& j, const std::string& name, FieldRule rule, double& v) {
    if (rule != FieldRule::optional) v = required_double(j, name);
    else if (const auto read = optional_double(j, name)) v = *read;
}

void read_value(const Json& j, const std::string& name, FieldRule, std::optional<double>& v) {
    v = optional_double(j, name);
}

void read_value(const Json& j, const std::string& name, FieldRule rule, int& v) {
    if (rule != FieldRule::optional) v = required_int(j, name);
    else if (const auto read = optional_int(j, name)) v = *read;
}

void read_value(const Json& j, const std::string& name, FieldRule rule, long& v) {
    if (rule != FieldRule::optional) v = required_int(j, name);
    else if (const auto read = optional_int(j, name)) v = *read;
}

void read_value(const Json& j, const std::string& name, FieldRule rule, std::string& v) {
    if (rule == FieldRule::id) v = read_id(j, name);
    else if (rule == FieldRule::required) v = required_string(j, name);
    else if (auto read = optional_string(j, name)) v = std::move(*read);
}

void read_value(const Json& j, const std::string& name, FieldRule, std::optional<std::string>& v) {
    v = optional_string(j, name);
}

void read_value(const Json& j, const std::string& name, FieldRule, std::vector<std::string>& v) {
    v = optional_strings(j, name);
}

void read_value(const Json& j, const std::string& name, FieldRule rule, std::vector<double>& v) {
    const Json* list = rule == FieldRule::optional ? optional_array(j, name)
                                                   : &required_array(j, name);
    v.clear();
    if (list)
        for (const Json& value : *list) v.push_back(as_double(value, name));
}

void write_value(Json& j, const std::string& name, FieldRule, double v) { j[name] = v; }

void write_value(Json& j, const std::string& name, FieldRule, const std::optional<double>& v) {
    if (v) j[name] = *v;
}

void write_value(Json& j, const std::string& name, FieldRule, int v) { j[name] = v; }

void write_value(Json& j, const std::string& name, FieldRule, long v) { j[name] = v; }

void write_value(Json& j, const std::string& name, FieldRule rule, const std::string& v) {
    if (rule != FieldRule::optional || !v.empty()) j[name] = v;
}

void write_value(Json& j, const std::string& name, FieldRule, const std::optional<std::string>& v) {
    if (v) j[name] = *v;
}

void write_value(Json& j, const std::string& name, FieldRule, const std::vector<std::string>& v) {
    j[name] = v;
}

void write_value(Json& j, const std::string& name, FieldRule rule, const std::vector<double>& v) {
    if (rule != FieldRule::optional || !v.empty()) j[name] = v;
}

}  // namespace fields_detail

}  // namespace shapesim
