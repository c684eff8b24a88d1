// Plain text tables of numbers as astronomers keep them: columns separated by blanks, '#'
// starting a comment, blank lines ignored (SExtractor's .conv filters, star-count histograms,
// power spectra). Each reader parses its own columns; this walks the lines.
#pragma once

#include <functional>
#include <iosfwd>
#include <string>

namespace shapesim {

/// The most rows a text table may hold; one more is an Error naming the file and line.
inline constexpr long max_text_rows = 1000000;

/// Calls row(text, line) for each line of `in` that holds more than blanks once a '#' and what
/// follows it are cut off; `line` counts every line from 1, blank and comment ones too. Error
/// naming `name` (and the line) past max_text_rows rows, or when the stream fails to read.
void for_each_text_row(std::istream& in, const std::string& name,
                       const std::function<void(const std::string& text, long line)>& row);

}  // namespace shapesim
