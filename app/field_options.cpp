#include "app/field_options.hpp"

#include "shapesim/fits_io.hpp"

#include <cmath>

namespace shapesim::app {

void FieldOptions::declare(ProgramOptions& options, const std::string& title,
                           const std::string& tile_help) {
    options.group(title).add_options()
        ("area", po::value(&area)->value_name("ARCMIN2")->notifier(in_range("area", 1e-9, 1e9)),
         "a square field of this area")
        ("size", po::value(&size)->value_name("ARCMIN")->multitoken(),
         "a field W H arcmin (one value: square)")
        ("pixels", po::value(&pixels)->value_name("NX")->multitoken(),
         "a field NX NY pixels of --pixel-scale (one value: square)")
        ("pixel-scale", po::value(&pixel_scale)->default_value(0.0398)
             ->notifier(in_range("pixel-scale", 1e-6, 3600.0)),
         "arcsec per pixel with --area/--size/--pixels (the HDF's by default), or of a --like "
         "image whose header has no WCS")
        ("ra", po::value(&ra)->default_value(0.0)->notifier(in_range("ra", -360.0, 360.0)),
         "field centre RA, degrees, with --area/--size (or a --like image without a WCS)")
        ("dec", po::value(&dec)->default_value(0.0)->notifier(in_range("dec", -90.0, 90.0)),
         "field centre Dec, degrees");
    if (!tile_help.empty())
        options.group(title).add_options()
            ("tile", po::value(&tile)->value_name("X0 Y0 X1 Y1")->multitoken(), tile_help.c_str());
}

FieldGeometry FieldOptions::field(const ProgramOptions& options) const {
    const int kinds = int(!options.common().like.empty()) + int(options.given("area")) +
                      int(options.given("size")) + int(options.given("pixels"));
    if (kinds != 1) throw po::error("give exactly one of --like, --area, --size, --pixels");
    // --like an image without a WCS takes --pixel-scale (and --ra/--dec), as detect does.
    if (!options.common().like.empty())
        return read_field_geometry(
            options.common().like,
            options.given("pixel-scale") ? std::optional(pixel_scale) : std::nullopt, ra, dec);
    if (options.given("area"))
        return make_field(std::sqrt(area), std::sqrt(area), pixel_scale, ra, dec);
    if (options.given("pixels")) {
        if (pixels.empty() || pixels.size() > 2) throw po::error("--pixels takes NX [NY]");
        const long nx = pixels[0], ny = pixels.size() == 2 ? pixels[1] : pixels[0];
        if (nx < 1 || ny < 1 || nx > 1000000000L || ny > 1000000000L)
            throw po::error("--pixels: 1 to 10^9 pixels a side");
        // make_field rounds W·60/scale back to whole pixels: NX·scale/60 returns NX exactly.
        return make_field(double(nx) * pixel_scale / 60.0, double(ny) * pixel_scale / 60.0,
                          pixel_scale, ra, dec);
    }
    if (size.empty() || size.size() > 2) throw po::error("--size takes W [H] arcmin");
    const double w = size[0], h = size.size() == 2 ? size[1] : size[0];
    if (!(w > 0.0 && h > 0.0 && w < 1e5 && h < 1e5)) throw po::error("--size: must be > 0 arcmin");
    return make_field(w, h, pixel_scale, ra, dec);
}

std::optional<Tile> FieldOptions::window(const ProgramOptions& options, const FieldGeometry& field,
                                         bool within) const {
    if (!options.given("tile")) return std::nullopt;
    if (tile.size() != 4) throw po::error("--tile takes four numbers: X0 Y0 X1 Y1");
    for (double v : tile)
        if (v != std::floor(v) || !(std::abs(v) < 2e9)) throw po::error("--tile: whole pixels");
    const Tile t{long(tile[0]), long(tile[1]), long(tile[2]), long(tile[3])};
    if (t.x1 < t.x0 || t.y1 < t.y0) throw po::error("--tile: X1 >= X0 and Y1 >= Y0 needed");
    if (within && (t.x0 < 1 || t.y0 < 1 || t.x1 > field.nx || t.y1 > field.ny))
        throw po::error("--tile: must lie within the field's 1.." + std::to_string(field.nx) +
                        " x 1.." + std::to_string(field.ny) + " pixels");
    return t;
}

void declare_star_options(ProgramOptions& options, StarCounts& stars, std::uint64_t& count,
                          std::string& histogram) {
    options.group("Stars").add_options()
        ("star-density", po::value(&stars.density)->default_value(0.0)
             ->notifier(in_range("star-density", 0.0, 1e8)), "stars per arcmin^2 (Poisson)")
        ("star-count", po::value(&count), "exactly this many stars instead")
        ("star-slope", po::value(&stars.slope)->default_value(0.1)
             ->notifier(in_range("star-slope", -10.0, 10.0)), "d log10 N / dm of the star counts")
        ("star-mag-min", po::value(&stars.mag_min)->default_value(18.0)
             ->notifier(in_range("star-mag-min", -100.0, 100.0)), "brightest star")
        ("star-mag-max", po::value(&stars.mag_max)
             ->notifier(in_range("star-mag-max", -100.0, 100.0)),
         "faintest star (default: --mag-limit)")
        ("star-histogram", po::value(&histogram)->value_name("FILE"),
         "star counts from lines 'mag_lo mag_hi count' instead of the power law");
}

}  // namespace shapesim::app
