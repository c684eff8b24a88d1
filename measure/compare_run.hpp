// shapesim-measure's comparison modes: --compare (the Table, the distances and the figures of
// measured catalogues, compare.hpp), --compare-paired (compare.hpp), --compare-colours
// (colours.hpp) and --compare-sky (noise.hpp). Their options, and the reading and writing
// around the library's work.
#pragma once

#include "app/log.hpp"
#include "app/options.hpp"
#include "shapesim/compare.hpp"

#include <ostream>
#include <string>
#include <vector>

namespace shapesim::app {

struct CompareSettings {
    std::vector<std::string> inputs, skies, colours, paired;
    double pair_radius = 0.1;  // arcsec
    std::string out = "compare", paper;
    std::string band = "I";  // the magnitudes' band, as the Table and figures label the cuts
    TableCuts cuts;

    /// The group "Compare".
    void declare(ProgramOptions& options);
    /// --compare: read the catalogues (and --paper's rows), write table.md, distances.md, the
    /// figures' data and script into -o (--output), and run gnuplot on it when gnuplot is there.
    void write_report(const Log& log) const;
    /// --compare-colours: the markdown colour report of galaxies brighter than `mag_limit`.
    void write_colours(std::ostream& out, double mag_limit, int threads) const;
    /// --compare-paired: the markdown table of the real galaxies paired with their replays.
    void write_paired(std::ostream& out) const;
    /// --compare-sky: the markdown table of the skies' noise records.
    void write_skies(std::ostream& out) const;
};

}  // namespace shapesim::app
