// Figures: a gnuplot script run where gnuplot is installed (a Debian package the first command
// installs), its chatter in a log beside the figures so stderr keeps to one-line messages.
#pragma once

#include <string>

namespace shapesim::app {

/// Run `script` with gnuplot, its stderr into `log_path`: true when it drew; false when gnuplot
/// is not installed (the caller says how to draw them later). Error naming the script when
/// gnuplot fails.
bool run_gnuplot(const std::string& script, const std::string& log_path);

}  // namespace shapesim::app
