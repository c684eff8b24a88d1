// Provenance of a program's FITS outputs: the run's effective options as primary-HDU keywords
// `HIERARCH OPTION <name> = '<value>'`, so a file says how it was made. (The prefix keeps a
// short option name from landing on a FITS keyword: `--bitpix` would overwrite BITPIX.)
// Options that cannot change a result (-j, -q, -v) and the outputs' own paths are left out: a
// run on more threads, or into another folder, writes the same bytes.
#pragma once

#include "app/options.hpp"
#include "shapesim/fits_io.hpp"

#include <string>
#include <vector>

namespace shapesim::app {

/// The options as keywords (one per option, its values space-separated), without -j/-q/-v and
/// the options naming `outputs` (the program's output files, e.g. {"output", "truth"}).
std::vector<FitsKeyword> provenance_keywords(const ProgramOptions& options,
                                             const std::vector<std::string>& outputs);

}  // namespace shapesim::app
