#include "shapesim/error.hpp"

namespace shapesim {

namespace {
std::string compose(const std::string& message, const std::string& file, long line,
                    const std::string& field) {
    std::string s;
    if (!file.empty()) {
        s += file;
        if (line > 0) s += ":" + std::to_string(line);
        s += ": ";
    }
    if (!field.empty()) s += field + ": ";
    return s + message;
}
}  // namespace

Error::Error(const std::string& message, std::string file, long line, std::string field)
    : std::runtime_error(compose(message, file, line, field)),
      message_(message),
      file_(std::move(file)),
      line_(line),
      field_(std::move(field)) {}

std::string Error::where_what() const { return what(); }

Error Error::at(std::string file, long line) const {
    return Error(message_, std::move(file), line, field_);
}

}  // namespace shapesim
