// Lines of text input, bounded, and plain text tables of numbers as astronomers keep them:
// columns separated by blanks, '#' starting a comment, blank lines ignored (SExtractor's .conv
// filters, star-count histograms, power spectra). Each reader parses its own columns; this
// reads and walks the lines.
#pragma once

#include <cstddef>
#include <functional>
#include <iosfwd>
#include <string>

namespace shapesim {

/// The longest line read from any text input (256 MiB: a record of n_max 1000, the records'
/// cap, is about 20 MB); a longer one is an Error naming its line.
inline constexpr std::size_t max_line_bytes = std::size_t(256) << 20;

/// One line of `in` into `text`, without its newline; false at the end of input. Read in
/// chunks, so that a line longer than max_line_bytes is refused once it passes the limit
/// (`name:line: a line longer than 256 MiB: not <kind> (no newline?)`), not after it has
/// filled memory (`/dev/zero`). A failed read is an Error naming `name`.
bool read_text_line(std::istream& in, std::string& text, const std::string& name, long line,
                    const char* kind);

/// The most rows a text table may hold; one more is an Error naming the file and line.
inline constexpr long max_text_rows = 1000000;

/// Calls row(text, line) for each line of `in` that holds more than blanks once a '#' and what
/// follows it are cut off; `line` counts every line from 1, blank and comment ones too. Error
/// naming `name` (and the line) past max_text_rows rows, on a line over max_line_bytes, or
/// when the stream fails to read.
void for_each_text_row(std::istream& in, const std::string& name,
                       const std::function<void(const std::string& text, long line)>& row);

}  // namespace shapesim
