// shapesim-detect: the objects of a real deep image → shapesim.source/1 on stdout, postage
// stamps in a multi-extension FITS file (paper §2.1; DESIGN §1, §2, §4).
// The work is in the library: detect.hpp (background, detection, photometry), stellarity.hpp
// (star/galaxy), stamps.hpp (stamps and local noise), sources.hpp (records).
#include "shapesim/app/atomic_file.hpp"
#include "shapesim/app/options.hpp"
#include "shapesim/app/run_main.hpp"
#include "shapesim/detect.hpp"
#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/psf.hpp"
#include "shapesim/records.hpp"
#include "shapesim/sources.hpp"

#include <cmath>
#include <iostream>
#include <memory>

namespace {

using namespace shapesim;
namespace po = app::po;

const char* const description =
    "Find the objects of a deep image: background, detection (SExtractor's algorithms via\n"
    "libsep), deblending, photometry, star/galaxy separation and postage stamps with the\n"
    "noise renormalised from each stamp's border. Galaxies go to stdout as\n"
    "shapesim.source/1 JSON lines; objects with stellarity above --star-threshold are\n"
    "dropped, or written to --stars (they model the PSF).\n"
    "\n"
    "Example (the shipped HDF-N data, AB zero point 22.08):\n"
    "  shapesim-detect hdfn_f814w_v2.fits --weight hdfn_f814w_v2_weight.fits \\\n"
    "      --zero-point 22.08 --stamps stamps.fits --stars stars.jsonl > sources.jsonl";

struct Settings {
    std::string image, weight, weight_type = "weight", filter = "default", filter_mode = "conv";
    std::string stamps, stars, segmentation, psf_image, psf_model;
    double pixel_scale = 0.0, ra = 0.0, dec = 0.0, zero_point = 0.0;
    double psf_fwhm = 0.15, psf_pixel_scale = 0.0, star_threshold = 0.97;
    std::vector<double> psf_box;
    bool no_clean = false, no_rescale = false;
    DetectionOptions detection;
    StampOptions stamp;
};

void declare(app::ProgramOptions& options, Settings& s) {
    using app::in_range;
    options.hidden().add_options()("image", po::value(&s.image)->required(), "input image");
    options.positional("image", 1);
    options.group("Input").add_options()
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
         "GAIN, e- per image unit, for Poisson errors (0: none)");
    options.group("Stars").add_options()
        ("psf-fwhm", po::value(&s.psf_fwhm)->value_name("ARCSEC")->default_value(0.15)
             ->notifier(in_range("psf-fwhm", 1e-6, 3600.0)),
         "Gaussian PSF for the stellarity (SEEING_FWHM), unless --psf-image/--psf-model")
        ("psf-image", po::value(&s.psf_image)->value_name("FILE"),
         "PSF image (finer or equal sampling) for the stellarity")
        ("psf-pixel-scale", po::value(&s.psf_pixel_scale)->value_name("ARCSEC")
             ->notifier(in_range("psf-pixel-scale", 1e-6, 3600.0)),
         "pixel scale of --psf-image (default: its PIXSCALE keyword)")
        ("psf-box", po::value(&s.psf_box)->value_name("ARCSEC")->multitoken(),
         "convolve --psf-image with square boxes of these widths first (the detector "
         "pixel, a drizzle drop: a subsampled TinyTim PSF lacks both)")
        ("psf-model", po::value(&s.psf_model)->value_name("FILE"),
         "PSF as a shapesim.shapelet/1 record (first line of FILE)")
        ("star-threshold", po::value(&s.star_threshold)->default_value(0.97)
             ->notifier(in_range("star-threshold", 0.0, 1.0)),
         "objects with stellarity above this are stars")
        ("stars", po::value(&s.stars)->value_name("FILE"),
         "write the stars' records here (default: drop them)");
    options.group("Output").add_options()
        ("stamps", po::value(&s.stamps)->value_name("FILE"),
         "write postage stamps (image, weight, mask per object) to this FITS file")
        ("stamp-factor", po::value(&s.stamp.size_factor)->default_value(3.0)
             ->notifier(in_range("stamp-factor", 0.0, 1e3)),
         "stamp side = factor · A_IMAGE + offset, pixels")
        ("stamp-offset", po::value(&s.stamp.size_offset)->default_value(5.0)
             ->notifier(in_range("stamp-offset", 1.0, 1e4)), "see --stamp-factor")
        ("border-width", po::value(&s.stamp.border_width)->default_value(2)
             ->notifier(in_range("border-width", 1, 1000)),
         "depth of the stamp border that sets the local noise, pixels")
        ("segmentation", po::value(&s.segmentation)->value_name("FILE"),
         "write the segmentation map (object labels = ids) to this FITS file");
}

std::vector<FitsKeyword> provenance(const app::ProgramOptions& options) {
    std::vector<FitsKeyword> keywords;
    for (const auto& [name, value] : options.settings()) keywords.emplace_back(name, value);
    return keywords;
}

int run(int argc, const char* const argv[]) {
    app::ProgramOptions options("shapesim-detect", "[OPTION]... IMAGE", description,
                                app::Common::quiet | app::Common::verbose |
                                    app::Common::config | app::Common::print_params);
    Settings s;
    declare(options, s);
    if (!options.parse(argc, argv)) return 0;
    const app::Log log("shapesim-detect", options.common().verbosity);

    s.detection.clean = !s.no_clean;
    s.detection.rescale_weight = !s.no_rescale;
    if (s.filter_mode == "matched") s.detection.filter_mode = FilterMode::matched;
    else if (s.filter_mode != "conv")
        throw po::error("--filter-mode: must be conv or matched, got '" + s.filter_mode + "'");
    if (s.filter != "default") s.detection.filter = read_filter_kernel(s.filter);
    if (options.given("ra") != options.given("dec"))
        throw po::error("--ra and --dec go together");
    if (!s.psf_image.empty() && !s.psf_model.empty())
        throw po::error("--psf-image and --psf-model exclude each other");
    // Refuse unwritable outputs before the work.
    for (const std::string* path : {&s.stamps, &s.stars, &s.segmentation})
        if (!path->empty()) app::check_writable(*path);

    // The image, its geometry and zero point.
    FitsReader fits(s.image, FitsStart::first_image);
    const ImageArray image = fits.read_image();
    SourceContext context;
    context.image = s.image;
    context.stamps = s.stamps;
    context.star_threshold = s.star_threshold;
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
            context.wcs = tan_wcs(s.ra, s.dec, s.pixel_scale, (image.cols() + 1) / 2.0,
                                  (image.rows() + 1) / 2.0);
    } else {
        throw Error("no WCS in the header: give --pixel-scale (and --ra/--dec for sky "
                    "positions)", fits.place());
    }
    if (options.given("zero-point")) context.zero_point = s.zero_point;
    else if (auto zp = header_zero_point(fits)) context.zero_point = *zp;
    else log.info("no zero point given or in the header: magnitudes use zero point 0");

    std::unique_ptr<ImageArray> inverse_variance;
    if (!s.weight.empty()) {
        FitsReader weight_fits(s.weight, FitsStart::first_image);
        inverse_variance = std::make_unique<ImageArray>(inverse_variance_from(
            weight_fits.read_image(), parse_noise_map_type(s.weight_type), weight_fits.place()));
        if (inverse_variance->rows() != image.rows() || inverse_variance->cols() != image.cols())
            throw Error("weight map is " + std::to_string(inverse_variance->cols()) + "×" +
                            std::to_string(inverse_variance->rows()) + " pixels, the image " +
                            std::to_string(image.cols()) + "×" + std::to_string(image.rows()),
                        weight_fits.place());
    }

    // The point-source locus for the stellarity.
    PointSourceLocus locus;
    if (!s.psf_image.empty()) {
        const PsfImage psf = read_psf_image(
            s.psf_image, options.given("psf-pixel-scale") ? std::optional(s.psf_pixel_scale)
                                                          : std::nullopt);
        locus = image_point_source_locus(convolve_boxes(psf.pixels, psf.pixel_scale, s.psf_box),
                                         psf.pixel_scale, context.pixel_scale);
    } else if (!s.psf_model.empty()) {
        JsonlReader reader(s.psf_model, {ShapeletRecord::schema});
        ShapeletRecord record;
        if (!reader.next_record(record)) throw Error("no PSF record", s.psf_model);
        ShapeletModel model = record.to_model();
        // To image pixels: β scales with the pixel-scale ratio; coefficients are per pixel
        // but the stellarity only needs the shape (flux is normalised out).
        model.beta_pix = record.beta / context.pixel_scale;
        locus = model_point_source_locus(model);
    } else {
        locus = gaussian_point_source_locus(s.psf_fwhm / context.pixel_scale);
    }
    log.verbose("point-source locus: FWHM ", locus.fwhm, " px, core fraction ", locus.ratio,
                " ± ", locus.scatter, " (r ", locus.r_core, " / ", locus.r_outer, " px)");

    const DetectionResult field = detect_sources(image, inverse_variance.get(), s.detection);
    log.info(field.objects.size(), " objects above ", s.detection.detect_thresh,
             "σ (background rms ", field.background_rms, ", weight scale ", field.weight_scale,
             ", correlated-noise factor ", field.noise_correlation, ")");

    context.noise_correlation = field.noise_correlation;
    if (inverse_variance && (field.weight_scale > 100.0 || field.weight_scale < 0.01))
        log.warn("the weight map's noise differs from the measured rms by a factor ",
                 1.0 / std::sqrt(field.weight_scale), " (is --weight-type ", s.weight_type,
                 " right?)");

    std::unique_ptr<FitsWriter> stamps;
    if (!s.stamps.empty())
        stamps = std::make_unique<FitsWriter>(s.stamps, "shapesim-detect", provenance(options));
    std::unique_ptr<app::AtomicTextFile> stars_file;
    std::unique_ptr<JsonlWriter> stars_out;
    if (!s.stars.empty()) {
        stars_file = std::make_unique<app::AtomicTextFile>(s.stars);
        stars_out = std::make_unique<JsonlWriter>(stars_file->stream(), s.stars);
    }
    JsonlWriter out(std::cout, "-");
    long n_stars = 0;
    for (const Detection& object : field.objects) {
        const CoreFraction core = core_fraction(field, object, locus);
        const double star = stellarity(core, locus);
        const bool is_star = star > s.star_threshold;
        std::unique_ptr<CutStamp> cut;
        if (stamps && (!is_star || stars_out)) {
            cut = std::make_unique<CutStamp>(
                cut_stamp(field, object, std::to_string(object.label), s.stamp));
            write_stamp(*stamps, cut->stamp);
        }
        const Json record = source_record(object, core, star, cut.get(), context).to_json();
        if (is_star) {
            ++n_stars;
            if (stars_out) stars_out->write(record);
        } else {
            out.write(record);
        }
        log.verbose("object ", object.label, " at (", object.x, ", ", object.y,
                    ") stellarity ", star);
    }
    if (!s.segmentation.empty()) {
        FitsWriter seg(s.segmentation, "shapesim-detect", provenance(options));
        FitsImageSpec spec{"SEGMENTATION", 32, {}, context.wcs, {}, {}};
        seg.write_image(field.segmentation.cast<double>(), spec);
        seg.commit();
    }
    if (stamps) stamps->commit();
    if (stars_file) stars_file->commit();
    log.info(out.count(), " galaxies, ", n_stars, " stars (stellarity > ", s.star_threshold,
             ") in ", log.elapsed(), " s");
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "shapesim-detect", run); }
