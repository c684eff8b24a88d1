// shapesim-detect: the objects of a real deep image → shapesim.source/1 on stdout, postage
// stamps in a multi-extension FITS file (paper §2.1; DESIGN §1, §2, §4).
// The work is in the library: detect.hpp (background, detection, photometry), stellarity.hpp
// (star/galaxy), stamps.hpp (stamps and local noise), sources.hpp (records).
#include "shapesim/app/atomic_file.hpp"
#include "shapesim/app/detection_run.hpp"
#include "shapesim/app/options.hpp"
#include "shapesim/app/provenance.hpp"
#include "shapesim/app/run_main.hpp"
#include "shapesim/bands.hpp"
#include "shapesim/detect.hpp"
#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/noise.hpp"
#include "shapesim/psf.hpp"
#include "shapesim/records.hpp"
#include "shapesim/sources.hpp"

#include <cmath>
#include <iostream>
#include <memory>
#include <optional>

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
    "      --zero-point 22.08 --stamps stamps.fits --stars stars.jsonl > sources.jsonl\n"
    "\n"
    "Several bands (dual-image mode): detect on IMAGE, measure every band of --bands in the\n"
    "same apertures (forced FLUX_AUTO) and cut its stamps in the same boxes, for\n"
    "shapesim-decompose's joint fit:\n"
    "  shapesim-detect detection_sci.fits --weight detection_wht.fits --pixel-scale 0.06 \\\n"
    "      --bands xdf.bands.jsonl --stamps stamps.fits > sources.jsonl";

struct Settings {
    app::DetectionSettings detection;
    std::string stamps, stars, segmentation, noise_model, bands;
    StampOptions stamp;
    SkyNoiseOptions noise;
};

void declare(app::ProgramOptions& options, Settings& s) {
    using app::in_range;
    s.detection.declare(options);
    options.group("Stars").add_options()
        ("stars", po::value(&s.stars)->value_name("FILE"),
         "write the stars' records here (default: drop them)");
    options.group("Bands").add_options()
        ("bands", po::value(&s.bands)->value_name("FILE"),
         "shapesim.band/1 lines (band, image, weight, zero_point, gain): measure each band in "
         "the detection's apertures and cut its stamps (<id>.<band>) in the same boxes");
    options.group("Output").add_options()
        ("stamps", po::value(&s.stamps)->value_name("FILE"),
         "write postage stamps (image, weight, mask per object) to this FITS file")
        ("stamp-factor", po::value(&s.stamp.size_factor)->default_value(3.0)
             ->notifier(in_range("stamp-factor", 0.0, 1e3)),
         "stamp side >= factor · A_IMAGE + offset, pixels (and >= the object's segment plus "
         "--stamp-sky-margin, and its Kron aperture; then grown x1.25 until the border is sky)")
        ("stamp-offset", po::value(&s.stamp.size_offset)->default_value(5.0)
             ->notifier(in_range("stamp-offset", 1.0, 1e4)), "see --stamp-factor")
        ("stamp-sky-margin", po::value(&s.stamp.sky_margin)->default_value(4)
             ->notifier(in_range("stamp-sky-margin", 0, 10000)),
         "sky pixels beyond the object's segment on each side of its stamp")
        ("stamp-max-side", po::value(&s.stamp.max_side)->default_value(513)
             ->notifier(in_range("stamp-max-side", 3, 100000)),
         "stamps are never grown beyond this side, pixels (flag stamp_not_sky)")
        ("border-width", po::value(&s.stamp.border_width)->default_value(2)
             ->notifier(in_range("border-width", 1, 1000)),
         "depth of the stamp border that sets the local noise, pixels")
        ("segmentation", po::value(&s.segmentation)->value_name("FILE"),
         "write the segmentation map (object labels = ids) to this FITS file")
        ("noise-model", po::value(&s.noise_model)->value_name("FILE"),
         "write the sky's measured noise (shapesim.noise/1: rms, 2-D autocorrelation, pixel "
         "quantiles; objects masked) to this file, for shapesim-render --noise-model")
        ("noise-radius", po::value(&s.noise.radius)->default_value(8)
             ->notifier(in_range("noise-radius", 0, 64)),
         "largest lag of the measured autocorrelation, pixels")
        ("noise-grow", po::value(&s.noise.grow)->default_value(2)
             ->notifier(in_range("noise-grow", 0, 100)),
         "sky pixels kept this far from every masked object and bad pixel, pixels")
        ("noise-mask-snr", po::value(&s.noise.mask_snr)->default_value(4.0)
             ->notifier(in_range("noise-mask-snr", 0.0, 1e9)),
         "mask only objects of at least this S/N (fainter ones are mostly the noise's own "
         "peaks; 0: mask all)");
}

int run(int argc, const char* const argv[]) {
    app::ProgramOptions options("shapesim-detect", "[OPTION]... IMAGE", description,
                                app::Common::quiet | app::Common::verbose |
                                    app::Common::config | app::Common::print_params);
    Settings s;
    declare(options, s);
    if (!options.parse(argc, argv)) return 0;
    const app::Log log("shapesim-detect", options.common().verbosity);

    // Refuse unwritable outputs before the work.
    for (const std::string* path : {&s.stamps, &s.stars, &s.segmentation, &s.noise_model})
        if (!path->empty()) app::check_writable(*path);

    std::vector<BandRecord> band_list;
    if (!s.bands.empty()) band_list = BandRecord::read_all(s.bands);
    app::DetectionRun detected = s.detection.run(options, log);
    const std::vector<BandField> bands =
        measure_bands(band_list, detected.field, s.detection.detection);
    s.stamp.gain = s.detection.detection.gain;  // source photon noise in the stamps' weights
    SourceContext& context = detected.context;
    context.stamps = s.stamps;
    const DetectionResult& field = detected.field;
    const PointSourceLocus& locus = detected.locus;
    // Measured before any output, so a field without enough sky fails with nothing written.
    std::optional<NoiseRecord> noise;
    if (!s.noise_model.empty()) {
        noise = measure_sky_noise(field, s.noise);
        noise->extra["image"] = s.detection.image;
    }
    const double star_threshold = s.detection.star_threshold;
    const std::vector<std::string> outputs = {"stamps", "stars", "segmentation", "noise-model"};
    std::unique_ptr<FitsWriter> stamps;
    if (!s.stamps.empty())
        stamps = std::make_unique<FitsWriter>(s.stamps, "shapesim-detect",
                                              app::provenance_keywords(options, outputs));
    std::unique_ptr<app::AtomicTextFile> stars_file;
    std::unique_ptr<JsonlWriter> stars_out;
    if (!s.stars.empty()) {
        stars_file = std::make_unique<app::AtomicTextFile>(s.stars);
        stars_out = std::make_unique<JsonlWriter>(stars_file->stream(), s.stars);
    }
    JsonlWriter out(std::cout, "-");
    long n_stars = 0, n_spikes = 0;
    for (const Detection& object : field.objects) {
        if (is_single_pixel_event(object.peak, object.flux_iso)) {  // not a star: no PSF
            ++n_spikes;
            continue;
        }
        const CoreFraction core = core_fraction(field, object, locus);
        const double star = stellarity(core, locus);
        const bool is_star = star > star_threshold;
        std::unique_ptr<CutStamp> cut;
        if (stamps && (!is_star || stars_out)) {
            cut = std::make_unique<CutStamp>(
                cut_stamp(field, object, std::to_string(object.label), s.stamp));
            write_stamp(*stamps, cut->stamp);
        }
        SourceRecord record = source_record(object, core, star, cut.get(), context);
        if (!bands.empty())
            add_bands(record, bands, std::size_t(object.label - 1), object, cut.get(),
                      stamps.get(), s.stamps, s.stamp);
        if (is_star) {
            ++n_stars;
            if (stars_out) stars_out->write(record.to_json());
        } else {
            out.write(record.to_json());
        }
        log.verbose("object ", object.label, " at (", object.x, ", ", object.y,
                    ") stellarity ", star);
    }
    if (!s.segmentation.empty()) {
        FitsWriter seg(s.segmentation, "shapesim-detect",
                       app::provenance_keywords(options, outputs));
        FitsImageSpec spec{"SEGMENTATION", 32, {}, context.wcs, {}, {}};
        seg.write_image(field.segmentation.cast<double>(), spec);
        seg.commit();
    }
    if (noise) {
        app::AtomicTextFile file(s.noise_model);
        JsonlWriter(file.stream(), s.noise_model).write(noise->to_json());
        file.commit();
        log.info("sky noise: rms ", noise->rms, " (MAD σ ", noise->mad_sigma, ") over ",
                 noise->pixels, " pixels; autocorrelation at (1,0) ", noise->correlation.at(1, 0),
                 ", (1,1) ", noise->correlation.at(1, 1), ", (2,0) ", noise->correlation.at(2, 0));
    }
    if (stamps) stamps->commit();
    if (stars_file) stars_file->commit();
    log.info(out.count(), " galaxies, ", n_stars, " stars (stellarity > ", star_threshold,
             ", through ", detected.locus_note, ") in ", log.elapsed(), " s");
    if (n_spikes > 0)
        log.info(n_spikes, " single-pixel events (cosmic rays, hot pixels: the peak holds ",
                 "≥ 75% of the flux) left out");
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "shapesim-detect", run); }
