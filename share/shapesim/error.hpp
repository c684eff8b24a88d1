// shapesim::Error — the one exception type of the library.
//
// Carries an optional place (file, 1-based line, field) so that `app::run_main` can print one
// GNU-style line: `shapesim-decompose: shapelets.jsonl:42: beta: must be > 0, got -0.3`.
// Foreign errors (cfitsio status, nlohmann exceptions) are wrapped into it where they enter.
#pragma once

#include <stdexcept>
#include <string>

namespace shapesim {

class Error : public std::runtime_error {
public:
    /// @param message what is wrong (no trailing newline, no program name)
    /// @param file    file the error is about ("-" for stdin; FITS places like `a.fits[SCI]`)
    /// @param line    1-based line in a text file, 0 when not applicable
    /// @param field   record field or header keyword, empty when not applicable
    explicit Error(const std::string& message, std::string file = {}, long line = 0,
                   std::string field = {});

    const std::string& message() const { return message_; }
    const std::string& file() const { return file_; }
    long line() const { return line_; }
    const std::string& field() const { return field_; }

    /// The place and message as one line: `file:line: field: message`.
    std::string where_what() const;

    /// A copy with the file (and line) set, for callers that know the place.
    Error at(std::string file, long line = 0) const;

private:
    std::string message_, file_;
    long line_;
    std::string field_;
};

/// Throw Error(message) unless `condition` holds; for argument checks in the library.
inline void require(bool condition, const std::string& message) {
    if (!condition) throw Error(message);
}

}  // namespace shapesim
