#include "app/detection_run.hpp"

#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/analytic_psf.hpp"
#include "shapesim/psf.hpp"
#include "shapesim/records.hpp"

#include <cmath>
#include <memory>
#include <optional>
#include <sstream>

namespace shapesim::app {

void DetectionSettings::declare(ProgramOptions& options, bool image_required) {
    DetectionSettings& s = *this;
    auto image = po::value(&s.image)->value_name("IMAGE");
    if (image_required) image->required();
    options.group("Input").add_options()
        ("input,i", image, "the image (FITS; cfitsio [HDU] syntax allowed), or the first argument")
        ("weight", po::value(&s.weight)->value_name("FILE"),
         "noise map of the image (same size; cfitsio [HDU] syntax allowed)")
        ("weight-type", po::value(&s.weight_type)->value_name("TYPE")->default_value("weight"),
         "what --weight holds: weight (inverse variance), rms or variance")
        ("pixel-scale", po::value(&s.pixel_scale)->value_name("ARCSEC")
             ->notifier(in_range("pixel-scale", 1e-6, 3600.0)),
         "pixel scale when the header has no WCS (arcsec/pixel)")
        ("ra", po::value(&s.ra)->value_name("DEG")->notifier(in_range("ra", 0.0, 360.0)),
         "with --pixel-scale: RA of the image centre (north-up TAN WCS)")
        ("dec", po::value(&s.dec)->value_name("DEG")->notifier(in_range("dec", -90.0, 90.0)),
         "with --pixel-scale: Dec of the image centre")
        ("zero-point", po::value(&s.zero_point)->value_name("MAG"),
         "AB magnitude of one image unit (default: header MAGZPT/ZP/PHOTFLAM…, else 0)");
    options.positional("input", 1);
    DetectionOptions& d = s.detection;
    options.group("Detection (SExtractor parameters)").add_options()
        ("detect-thresh", po::value(&d.detect_thresh)->default_value(1.3)
             ->notifier(in_range("detect-thresh", 1e-3, 1e6)), "DETECT_THRESH, σ")
        ("analysis-thresh", po::value(&d.analysis_thresh)->default_value(0.9)
             ->notifier(in_range("analysis-thresh", 1e-3, 1e6)), "ANALYSIS_THRESH, σ")
        ("min-area", po::value(&d.min_area)->default_value(5)
             ->notifier(in_range("min-area", 1, 1 << 30)), "DETECT_MINAREA, pixels")
        ("deblend-nthresh", po::value(&d.deblend_nthresh)->default_value(32)
             ->notifier(in_range("deblend-nthresh", 1, 1024)), "DEBLEND_NTHRESH")
        ("deblend-mincont", po::value(&d.deblend_mincont)->default_value(0.03)
             ->notifier(in_range("deblend-mincont", 0.0, 1.0)), "DEBLEND_MINCONT")
        ("clean-param", po::value(&d.clean_param)->default_value(1.0)
             ->notifier(in_range("clean-param", 1e-6, 1e6)), "CLEAN_PARAM")
        ("no-clean", po::bool_switch(&s.no_clean), "CLEAN N")
        ("back-size", po::value(&d.back_size)->default_value(64)
             ->notifier(in_range("back-size", 1, 1 << 20)), "BACK_SIZE, pixels")
        ("back-filter-size", po::value(&d.back_filter_size)->default_value(3)
             ->notifier(in_range("back-filter-size", 1, 1024)), "BACK_FILTERSIZE, tiles")
        ("filter", po::value(&s.filter)->value_name("FILE")->default_value("default"),
         "detection filter: a SExtractor .conv file, or 'default' (3×3 pyramid)")
        ("filter-mode", po::value(&s.filter_mode)->default_value("conv"),
         "conv (SExtractor) or matched (libsep's noise-aware matched filter)")
        ("no-weight-rescale", po::bool_switch(&s.no_rescale),
         "use the weight map as given (default: scale it to the measured rms)")
        ("gain", po::value(&d.gain)->default_value(0.0)
             ->notifier(in_range("gain", 0.0, 1e30)),
         "GAIN, e- per image unit, for Poisson errors and the stamps' weights (0: none)")
        ("saturation", po::value(&s.saturation)->value_name("LEVEL")
             ->notifier(in_range("saturation", 0.0, 1e300)),
         "SATUR_LEVEL, image units as read: objects reaching it are flagged 'saturated' and set "
         "aside with the stars (default: the header's SATURATE; 0: none)")
        ("tile-side", po::value(&s.tile_side)->value_name("SIDE")->default_value("auto"),
         "detect in tiles of SIDE² pixels (rounded up to whole --back-size cells), one at a "
         "time, so that memory is bounded by the tile; auto: tiles of 2048² when the image has "
         "more than 4096² pixels; none: the whole image at once")
        ("tile-margin", po::value(&s.tile_margin)->value_name("PIXELS")->default_value(256)
             ->notifier(in_range("tile-margin", 0L, 1L << 20)),
         "pixels read beyond each tile on every side (rounded up to whole --back-size cells): "
         "more than the largest object's half-size");
    options.group("Stars").add_options()
        ("psf-fwhm", po::value(&s.psf_fwhm)->value_name("ARCSEC")->default_value(0.15)
             ->notifier(in_range("psf-fwhm", 1e-6, 3600.0)),
         "Gaussian PSF for the stellarity (SEEING_FWHM), unless --psf-image, --psf or "
         "--psf-analytic")
        ("psf-image", po::value(&s.psf_image)->value_name("FILE"),
         "PSF image (finer or equal sampling) for the stellarity")
        ("psf-pixel-scale", po::value(&s.psf_pixel_scale)->value_name("ARCSEC")
             ->notifier(in_range("psf-pixel-scale", 1e-6, 3600.0)),
         "pixel scale of --psf-image (default: its PIXSCALE keyword, else its WCS)")
        ("psf-box", po::value(&s.psf_box)->value_name("ARCSEC")->multitoken(),
         "convolve --psf-image with square boxes of these widths first (the detector "
         "pixel, a drizzle drop: a subsampled TinyTim PSF lacks both)")
        ("psf-analytic", po::value(&s.psf_analytic)->value_name("SPEC"),
         "analytic PSF for the stellarity: gaussian:FWHM, moffat:FWHM[,BETA], "
         "airy:LAMBDA_OVER_D[,OBSCURATION], optionally ;jitter=SIGMA (arcsec)")
        ("psf", po::value(&s.psf_model)->value_name("FILE"),
         "PSF as a shapesim.shapelet/1 record (first line of FILE)")
        ("star-threshold", po::value(&s.star_threshold)->default_value(0.97)
             ->notifier(in_range("star-threshold", 0.0, 1.0)),
         "objects with stellarity above this are stars");
    options.alias("psf-model", "psf");
}

namespace {

// The options' values into DetectionOptions, and the combinations a single option cannot
// refuse (po::error, so the message points to --help).
void check_options(DetectionSettings& s, const ProgramOptions& options) {
    s.detection.clean = !s.no_clean;
    s.detection.rescale_weight = !s.no_rescale;
    if (s.filter_mode == "matched") s.detection.filter_mode = FilterMode::matched;
    else if (s.filter_mode != "conv")
        throw po::error("--filter-mode: must be conv or matched, got '" + s.filter_mode + "'");
    if (s.filter != "default") s.detection.filter = read_filter_kernel(s.filter);
    if (options.given("ra") != options.given("dec"))
        throw po::error("--ra and --dec go together");
    if (int(!s.psf_image.empty()) + int(!s.psf_model.empty()) + int(!s.psf_analytic.empty()) > 1)
        throw po::error("--psf-image, --psf and --psf-analytic exclude each other");
    if (!s.psf_analytic.empty()) {
        try {
            parse_analytic_psf(s.psf_analytic);
        } catch (const Error& e) {
            throw po::error("--psf-analytic: " + e.message());
        }
    }
}

// The image's geometry (its WCS, else --pixel-scale and --ra/--dec) and zero point (given,
// else the header's, else 0) into `context`.
void read_geometry(const DetectionSettings& s, const ProgramOptions& options, const Log& log,
                   FitsReader& fits, const ImageSize& size, SourceContext& context) {
    if (has_wcs(fits)) {
        context.wcs = read_wcs(fits);
        context.pixel_scale = context.wcs->pixel_scale_arcsec();
        if (options.given("pixel-scale") &&
            std::abs(s.pixel_scale / context.pixel_scale - 1.0) > 1e-3)
            log.warn("--pixel-scale ", s.pixel_scale, " differs from the header WCS (",
                     context.pixel_scale, "\"/pixel); using the header");
    } else if (options.given("pixel-scale")) {
        context.pixel_scale = s.pixel_scale;
        if (options.given("ra"))
            context.wcs = tan_wcs(s.ra, s.dec, s.pixel_scale, (size.nx + 1) / 2.0,
                                  (size.ny + 1) / 2.0);
    } else {
        throw Error("no WCS in the header: give --pixel-scale (and --ra/--dec for sky "
                    "positions)", fits.place());
    }
    if (options.given("zero-point")) context.zero_point = s.zero_point;
    else if (auto zp = header_zero_point(fits)) context.zero_point = *zp;
    else log.info("no zero point given or in the header: magnitudes use zero point 0");
}

// The --weight map, opened, its size checked against the image's (Error otherwise).
std::optional<FitsReader> open_weight(const DetectionSettings& s, const ImageSize& image) {
    if (s.weight.empty()) return std::nullopt;
    FitsReader weight_fits(s.weight, FitsStart::first_image);
    const ImageSize size = weight_fits.image_size();
    if (size.nx != image.nx || size.ny != image.ny)
        throw Error("weight map is " + std::to_string(size.nx) + "×" + std::to_string(size.ny) +
                        " pixels, the image " + std::to_string(image.nx) + "×" +
                        std::to_string(image.ny),
                    weight_fits.place());
    return weight_fits;
}

// The weight map's pixels in `window` (all of it: the whole map) as inverse variance.
std::unique_ptr<ImageArray> read_inverse_variance(const DetectionSettings& s,
                                                  std::optional<FitsReader>& weight_fits,
                                                  const Tile* window) {
    if (!weight_fits) return nullptr;
    const ImageArray map = window ? weight_fits->read_region(window->x0, window->y0,
                                                             window->x1 - window->x0 + 1,
                                                             window->y1 - window->y0 + 1)
                                  : weight_fits->read_image();
    return std::make_unique<ImageArray>(
        inverse_variance_from(map, parse_noise_map_type(s.weight_type), weight_fits->place()));
}

// The point-source locus for the stellarity, from --psf-image, --psf or the Gaussian of
// --psf-fwhm, and the note that names it in the summary line.
void point_source_locus(const DetectionSettings& s, const ProgramOptions& options,
                        double pixel_scale, DetectionRun& r) {
    PointSourceLocus& locus = r.locus;
    if (!s.psf_image.empty()) {
        const PsfImage psf = read_psf_image(
            s.psf_image, options.given("psf-pixel-scale") ? std::optional(s.psf_pixel_scale)
                                                          : std::nullopt);
        locus = image_point_source_locus(convolve_boxes(psf.pixels, psf.pixel_scale, s.psf_box),
                                         psf.pixel_scale, pixel_scale);
        r.locus_note = "the PSF image " + s.psf_image;
    } else if (!s.psf_analytic.empty()) {
        // The profile sampled five times finer than the image, out to 8 FWHM (and 4σ of
        // jitter), integrated over the image's pixels as a PSF image is.
        const AnalyticPsf psf = parse_analytic_psf(s.psf_analytic);
        const double fine = pixel_scale / 5.0;
        const double reach = 8.0 * psf.nominal_fwhm() + 4.0 * psf.jitter;
        const int side = 2 * int(std::min(std::ceil(reach / fine), 1000.0)) + 1;
        locus = image_point_source_locus(analytic_psf_image(psf, fine, side), fine, pixel_scale);
        r.locus_note = "the analytic PSF " + psf.describe();
    } else if (!s.psf_model.empty()) {
        // The stellarity needs the shape in image pixels; the flux is normalised out.
        const ShapeletModel model = read_psf_model(s.psf_model, pixel_scale);
        locus = model_point_source_locus(model);
        r.locus_note = "the PSF model " + s.psf_model;
    } else {
        locus = gaussian_point_source_locus(s.psf_fwhm / pixel_scale);
        std::ostringstream note;
        note << "a Gaussian PSF of FWHM " << s.psf_fwhm << "\""
             << (options.given("psf-fwhm") ? ""
                                           : ", the --psf-fwhm default; give --psf or "
                                             "--psf-image for this image's own");
        r.locus_note = note.str();
    }
}

// A weight map whose noise is a factor of 10 or more from the measured rms: the wrong
// --weight-type, more likely than a drizzle's scale.
bool weight_scale_suspect(const DetectionResult& field) {
    return field.weight_scale > 100.0 || field.weight_scale < 0.01;
}

// What the detection found, and what a user should doubt: pixels with no data, a weight map
// whose scale is far from the measured noise (the wrong --weight-type?).
void report_detection(const DetectionSettings& s, const Log& log, const DetectionResult& field,
                      bool weighted) {
    log.info(field.objects.size(), " objects above ", s.detection.detect_thresh,
             "σ (background rms ", field.background_rms, ", weight scale ", field.weight_scale,
             ", correlated-noise factor ", field.noise_correlation, ")");
    if (field.zero_noise_pixels > 0)
        log.warn(field.zero_noise_pixels, " pixels with no data (0 with every neighbour 0, or "
                 "no noise: a zero-filled border?) are treated as bad; give a weight map to say "
                 "so");
    if (weighted && weight_scale_suspect(field))
        log.warn("the weight map's noise differs from the measured rms by a factor ",
                 1.0 / std::sqrt(field.weight_scale), " (is --weight-type ", s.weight_type,
                 " right?)");
}


// What every tile of a run shares: the image and weight map, open; the image's geometry and
// zero point; the saturation level; the point-source locus.
struct DetectionInput {
    FitsReader fits;
    std::optional<FitsReader> weight;
    ImageSize size;
    DetectionRun base;  ///< context and locus of the whole image; no field
};

DetectionInput open_input(DetectionSettings& s, const ProgramOptions& options, const Log& log) {
    check_options(s, options);
    DetectionInput in{FitsReader(s.image, FitsStart::first_image), std::nullopt, {}, {}};
    in.size = in.fits.image_size();
    DetectionRun& r = in.base;
    r.context.image = s.image;
    r.context.star_threshold = s.star_threshold;
    read_geometry(s, options, log, in.fits, in.size, r.context);
    // The saturation level: given, else the header's SATURATE (SExtractor's SATUR_KEY).
    const std::optional<double> level = options.given("saturation")
                                            ? std::optional(s.saturation)
                                            : in.fits.optional_double("SATURATE");
    if (level && *level > 0.0) s.detection.saturation = *level;
    in.weight = open_weight(s, in.size);
    point_source_locus(s, options, r.context.pixel_scale, r);
    const PointSourceLocus& locus = r.locus;
    log.verbose("point-source locus: FWHM ", locus.fwhm, " px, core fraction ", locus.ratio,
                " ± ", locus.scatter, " (r ", locus.r_core, " / ", locus.r_outer, " px)");
    return in;
}

// Detection on `window` of the image (null: all of it), as an image of its own.
DetectionRun detect_window(const DetectionSettings& s, DetectionInput& in, const Tile* window) {
    DetectionRun r = in.base;
    std::unique_ptr<ImageArray> inverse_variance = read_inverse_variance(s, in.weight, window);
    {
        const ImageArray image =
            window ? in.fits.read_region(window->x0, window->y0, window->x1 - window->x0 + 1,
                                         window->y1 - window->y0 + 1)
                   : in.fits.read_image();
        if (window && r.context.wcs) r.context.wcs = r.context.wcs->cutout(window->x0, window->y0);
        r.field = detect_sources(image, inverse_variance.get(), s.detection);
    }
    r.context.noise_correlation = r.field.noise_correlation;
    r.context.background_rms = r.field.background_rms;
    return r;
}

// The tiles' side from --tile-side, rounded up to whole background cells (so that every tile's
// mesh is the image's); 0: the whole image in one piece.
long chosen_tile_side(const DetectionSettings& s, const ImageSize& size) {
    long side = 0;
    if (s.tile_side == "none") return 0;
    if (s.tile_side == "auto") {
        if (double(size.nx) * double(size.ny) <= 4096.0 * 4096.0) return 0;
        side = 2048;
    } else {
        std::size_t used = 0;
        try {
            side = std::stol(s.tile_side, &used);
        } catch (const std::exception&) {
            used = 0;
        }
        if (used != s.tile_side.size() || side < 16 || side > (1L << 30))
            throw po::error(
                "--tile-side: must be auto, none or a side of at least 16 pixels, got '" +
                s.tile_side + "'");
    }
    const long cell = s.detection.back_size;
    side = (side + cell - 1) / cell * cell;
    return side >= size.nx && side >= size.ny ? 0 : side;
}

// The whole image at once, reported.
DetectionRun detect_whole(const DetectionSettings& s, DetectionInput& in, const Log& log) {
    DetectionRun r = detect_window(s, in, nullptr);
    report_detection(s, log, r.field, in.weight.has_value());
    return r;
}

}  // namespace

DetectionRun DetectionSettings::run(const ProgramOptions& options, const Log& log) {
    DetectionInput in = open_input(*this, options, log);
    return detect_whole(*this, in, log);
}

TiledRun DetectionSettings::run_tiles(const ProgramOptions& options, const Log& log,
                                      const TileSink& sink) {
    DetectionInput in = open_input(*this, options, log);
    const long side = chosen_tile_side(*this, in.size);
    TiledRun tiled;
    if (side == 0) {
        DetectionRun r = detect_whole(*this, in, log);
        tiled.tiles.push_back({{1, 1, in.size.nx, in.size.ny}, {1, 1, in.size.nx, in.size.ny}});
        std::vector<std::size_t> all(r.field.objects.size());
        for (std::size_t k = 0; k < all.size(); ++k) all[k] = k;
        sink(r, tiled.tiles.front(), all);
        return tiled;
    }
    const long cell = detection.back_size;
    const long margin = (tile_margin + cell - 1) / cell * cell;
    tiled.tiles = tile_windows(in.size.nx, in.size.ny, side, margin);
    log.info("the ", in.size.nx, "×", in.size.ny, " image in ", tiled.tiles.size(),
             " tiles of ", side, "² pixels, each read with a margin of ", margin);
    long mis_scaled = 0;  // tiles whose weight map is far from their measured noise
    double first_factor = 1.0;
    for (std::size_t t = 0; t < tiled.tiles.size(); ++t) {
        const TileWindow& tile = tiled.tiles[t];
        DetectionRun r = detect_window(*this, in, &tile.window);
        const long nx = tile.window.x1 - tile.window.x0 + 1,
                   ny = tile.window.y1 - tile.window.y0 + 1;
        std::vector<std::size_t> owned;
        for (std::size_t k = 0; k < r.field.objects.size(); ++k) {
            Detection& d = r.field.objects[k];
            if (!tile.core.owns(d.x + double(tile.window.x0 - 1), d.y + double(tile.window.y0 - 1)))
                continue;
            owned.push_back(k);
            // Reaching the window's edge where the image goes on: the tile cut it.
            if ((d.xmin <= 1 && tile.window.x0 > 1) || (d.ymin <= 1 && tile.window.y0 > 1) ||
                (d.xmax >= nx && tile.window.x1 < in.size.nx) ||
                (d.ymax >= ny && tile.window.y1 < in.size.ny)) {
                d.flags.push_back("tile_truncated");
                ++tiled.truncated;
            }
        }
        log.info("tile ", t + 1, " of ", tiled.tiles.size(), " (x ", tile.core.x0, "–",
                 tile.core.x1, ", y ", tile.core.y0, "–", tile.core.y1, "): ", owned.size(),
                 " objects above ", detection.detect_thresh, "σ (background rms ",
                 r.field.background_rms, ", weight scale ", r.field.weight_scale,
                 ", correlated-noise factor ", r.field.noise_correlation, ")");
        if (r.field.zero_noise_pixels > 0)
            log.warn("tile ", t + 1, ": ", r.field.zero_noise_pixels,
                     " pixels with no data (0 with every neighbour 0, or no noise) are treated "
                     "as bad");
        if (in.weight && weight_scale_suspect(r.field) && mis_scaled++ == 0)
            first_factor = 1.0 / std::sqrt(r.field.weight_scale);
        sink(r, tile, owned);
    }
    if (mis_scaled > 0)
        log.warn("in ", mis_scaled, " of ", tiled.tiles.size(), " tiles the weight map's noise "
                 "differs from the measured rms by a factor such as ", first_factor,
                 " (is --weight-type ", weight_type, " right?)");
    if (tiled.truncated > 0)
        log.warn(tiled.truncated, " objects reach the edge of their tile's window and are cut "
                 "by it (flag tile_truncated): give a larger --tile-margin than ", margin);
    return tiled;
}

void shift_to_image(Json& record, const TileWindow& tile, long id_offset) {
    if (tile.window.x0 == 1 && tile.window.y0 == 1 && id_offset == 0) return;
    const long dx = tile.window.x0 - 1, dy = tile.window.y0 - 1;
    const std::pair<const char*, long> moves[] = {{"x", dx},      {"x_peak", dx}, {"x_asym", dx},
                                                  {"y", dy},      {"y_peak", dy}, {"y_asym", dy}};
    for (const auto& [key, by] : moves)
        if (auto it = record.find(key); it != record.end() && it->is_number())
            *it = it->is_number_integer() ? Json(it->get<long>() + by)
                                          : Json(it->get<double>() + double(by));
    if (id_offset != 0)
        if (auto it = record.find("id"); it != record.end() && it->is_string())
            *it = std::to_string(std::stol(it->get<std::string>()) + id_offset);
}

void declare_stamp_options(po::options_description_easy_init& add, StampOptions& stamp) {
    add
        ("stamp-factor", po::value(&stamp.size_factor)->default_value(3.0)
             ->notifier(in_range("stamp-factor", 0.0, 1e3)),
         "stamp side >= factor · A_IMAGE + offset, pixels (and >= the object's segment plus "
         "--stamp-sky-margin, and its Kron aperture; then grown x1.25 until the border is sky)")
        ("stamp-offset", po::value(&stamp.size_offset)->default_value(5.0)
             ->notifier(in_range("stamp-offset", 1.0, 1e4)), "see --stamp-factor")
        ("stamp-sky-margin", po::value(&stamp.sky_margin)->default_value(4)
             ->notifier(in_range("stamp-sky-margin", 0, 10000)),
         "sky pixels beyond the object's segment on each side of its stamp")
        ("stamp-max-side", po::value(&stamp.max_side)->default_value(513)
             ->notifier(in_range("stamp-max-side", 3, 100000)),
         "stamps are never grown beyond this side, pixels (flag stamp_not_sky)")
        ("border-width", po::value(&stamp.border_width)->default_value(2)
             ->notifier(in_range("border-width", 1, 1000)),
         "depth of the stamp border that sets the local noise, pixels");
}

void declare_sky_noise_options(po::options_description_easy_init& add, SkyNoiseOptions& noise) {
    add
        ("noise-radius", po::value(&noise.radius)->default_value(8)
             ->notifier(in_range("noise-radius", 0, 64)),
         "largest lag of the measured autocorrelation, pixels")
        ("noise-grow", po::value(&noise.grow)->default_value(2)
             ->notifier(in_range("noise-grow", 0, 100)),
         "sky pixels kept this far from every masked object and bad pixel, pixels")
        ("noise-mask-snr", po::value(&noise.mask_snr)->default_value(4.0)
             ->notifier(in_range("noise-mask-snr", 0.0, 1e9)),
         "mask only objects of at least this S/N (fainter ones are mostly the noise's own "
         "peaks; 0: mask all)");
}

}  // namespace shapesim::app
