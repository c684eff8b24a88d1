// The sky field of a program that makes a field (shapesim-sample, shapesim-render): --like
// IMAGE (Common::like), or --area / --size / --pixels with --pixel-scale, --ra, --dec; and
// --tile, a window of its pixels. One declaration, one reading, so both programs agree on a field.
#pragma once

#include "app/options.hpp"
#include "shapesim/geometry.hpp"
#include "shapesim/sample.hpp"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace shapesim::app {

struct FieldOptions {
    double area = 0.0, pixel_scale = 0.0398, ra = 0.0, dec = 0.0;
    std::vector<double> size, tile;
    std::vector<long> pixels;

    /// Add the options to `options`' group `title`; `tile_help` says what --tile does (empty:
    /// no --tile).
    void declare(ProgramOptions& options, const std::string& title, const std::string& tile_help);
    /// The field: exactly one of --like, --area, --size, --pixels (po::error otherwise).
    FieldGeometry field(const ProgramOptions& options) const;
    /// The --tile window, if given (po::error unless four whole numbers, X1 ≥ X0, Y1 ≥ Y0, and,
    /// with `within`, inside the field).
    std::optional<Tile> window(const ProgramOptions& options, const FieldGeometry& field,
                               bool within) const;
};

/// The group "Stars" of a program that draws stars (shapesim-sample): --star-density,
/// --star-count (into `count`), --star-slope, --star-mag-min, --star-mag-max and
/// --star-histogram (its FILE into `histogram`), in that order.
void declare_star_options(ProgramOptions& options, StarCounts& stars, std::uint64_t& count,
                          std::string& histogram);

}  // namespace shapesim::app
