// shapesim-detect: the objects of a real deep image → shapesim.source/1 on stdout, postage
// stamps in a multi-extension FITS file (paper §2.1; DESIGN §1, §2, §4).
// The work is in the library: detect.hpp (background, detection, photometry), stellarity.hpp
// (star/galaxy), stamps.hpp (stamps and local noise), sources.hpp (records).
#include "app/detection_run.hpp"
#include "app/options.hpp"
#include "app/provenance.hpp"
#include "app/run_main.hpp"
#include "shapesim/atomic_file.hpp"
#include "shapesim/bands.hpp"
#include "shapesim/detect.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/noise.hpp"
#include "shapesim/records.hpp"
#include "shapesim/sources.hpp"

#include <cmath>
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
    s.detection.declare(options);
    options.group("Stars").add_options()
        ("stars", po::value(&s.stars)->value_name("FILE"),
         "write the stars' records here (default: drop them)");
    options.group("Bands").add_options()
        ("bands", po::value(&s.bands)->value_name("FILE"),
         "shapesim.band/1 lines (band, image, weight, zero_point, gain): measure each band in "
         "the detection's apertures and cut its stamps (<id>.<band>) in the same boxes");
    // The stamps' and the sky noise's own options are shared plumbing (app/detection_run.hpp).
    po::options_description_easy_init output = options.group("Output").add_options();
    output("stamps", po::value(&s.stamps)->value_name("FILE"),
           "write postage stamps (image, weight, mask per object) to this FITS file");
    app::declare_stamp_options(output, s.stamp);
    output("segmentation", po::value(&s.segmentation)->value_name("FILE"),
           "write the segmentation map (object labels = ids) to this FITS file")
          ("noise-model", po::value(&s.noise_model)->value_name("FILE"),
           "write the sky's measured noise (shapesim.noise/1: rms, 2-D autocorrelation, pixel "
           "quantiles; objects masked) to this file, for shapesim-render --noise-model");
    app::declare_sky_noise_options(output, s.noise);
}

int run(int argc, const char* const argv[]) {
    app::ProgramOptions options("shapesim-detect", "[OPTION]... IMAGE", description,
                                app::Common::output | app::Common::quiet | app::Common::verbose |
                                    app::Common::config | app::Common::print_params);
    Settings s;
    declare(options, s);
    if (!options.parse(argc, argv)) return 0;
    const app::Log log("shapesim-detect", options.common().verbosity);

    // Refuse unwritable outputs before the work.
    for (const std::string* path : {&s.stamps, &s.stars, &s.segmentation, &s.noise_model})
        if (!path->empty()) check_writable(*path);
    AtomicTextFile file(options.common().output_or_stdout());

    // Stamps, the segmentation map, the sky's noise and other bands are made from the whole
    // image at once; the catalogue alone is made tile by tile (--tile-side).
    const bool whole_image_outputs =
        !s.stamps.empty() || !s.segmentation.empty() || !s.noise_model.empty() || !s.bands.empty();
    if (whole_image_outputs && options.given("tile-side") && s.detection.tile_side != "none")
        throw po::error("--tile-side: --stamps, --segmentation, --noise-model and --bands are made "
                        "from the whole image (give --tile-side none, or leave them out)");
    CatalogueTally tally;
    std::string locus_note;
    long written = 0;
    if (!whole_image_outputs) {
        JsonlWriter out(file.stream(), file.name());
        std::unique_ptr<AtomicTextFile> stars_file;
        std::unique_ptr<JsonlWriter> stars_out;
        if (!s.stars.empty()) {
            stars_file = std::make_unique<AtomicTextFile>(s.stars);
            stars_out = std::make_unique<JsonlWriter>(stars_file->stream(), s.stars);
        }
        long id_offset = 0;
        s.detection.run_tiles(options, log, [&](app::DetectionRun& detected, const TileWindow& tile,
                                                const std::vector<std::size_t>& owned) {
            locus_note = detected.locus_note;
            const CatalogueTally t = catalogue_sources(
                detected.field, detected.locus, detected.context, {}, s.stamp, nullptr, false,
                [&](const Detection&, const SourceRecord& record, bool is_star, double star) {
                    Json json = record.to_json();
                    app::shift_to_image(json, tile, id_offset);
                    if (!is_star) out.write(json);
                    else if (stars_out) stars_out->write(json);
                    log.verbose("object ", json.at("id").get<std::string>(), " at (",
                                json.at("x").get<double>(), ", ", json.at("y").get<double>(),
                                ") stellarity ", star);
                },
                &owned);
            tally.stars += t.stars;
            tally.saturated += t.saturated;
            tally.single_pixel_events += t.single_pixel_events;
            id_offset += long(detected.field.objects.size());
        });
        if (stars_file) stars_file->commit();
        file.commit();
        written = out.count();
    } else {
        std::vector<BandRecord> band_list;
        if (!s.bands.empty()) band_list = BandRecord::read_all(s.bands);
        app::DetectionRun detected = s.detection.run(options, log);
        locus_note = detected.locus_note;
        const std::vector<BandField> bands =
            measure_bands(band_list, detected.field, s.detection.detection);
        s.stamp.gain = s.detection.detection.gain;  // source photon noise in the stamps' weights
        SourceContext& context = detected.context;
        context.stamps = s.stamps;
        const DetectionResult& field = detected.field;
        // Measured before any output, so a field without enough sky fails with nothing written.
        std::optional<NoiseRecord> noise;
        if (!s.noise_model.empty()) {
            noise = measure_sky_noise(field, s.noise);
            noise->extra["image"] = s.detection.image;
        }
        const std::vector<std::string> outputs = {"stamps", "stars", "segmentation", "noise-model"};
        std::unique_ptr<FitsWriter> stamps;
        if (!s.stamps.empty())
            stamps = std::make_unique<FitsWriter>(s.stamps, "shapesim-detect",
                                                  app::provenance_keywords(options, outputs));
        std::unique_ptr<AtomicTextFile> stars_file;
        std::unique_ptr<JsonlWriter> stars_out;
        if (!s.stars.empty()) {
            stars_file = std::make_unique<AtomicTextFile>(s.stars);
            stars_out = std::make_unique<JsonlWriter>(stars_file->stream(), s.stars);
        }
        JsonlWriter out(file.stream(), file.name());
        tally = catalogue_sources(
            field, detected.locus, context, bands, s.stamp, stamps.get(), stars_out != nullptr,
            [&](const Detection& object, const SourceRecord& record, bool is_star, double star) {
                if (!is_star) out.write(record.to_json());
                else if (stars_out) stars_out->write(record.to_json());
                log.verbose("object ", object.label, " at (", object.x, ", ", object.y,
                            ") stellarity ", star);
            });
        if (!s.segmentation.empty()) {
            FitsWriter seg(s.segmentation, "shapesim-detect",
                           app::provenance_keywords(options, outputs));
            FitsImageSpec spec{"SEGMENTATION", 32, {}, context.wcs, {}, {}};
            seg.write_image(field.segmentation.cast<double>(), spec);
            seg.commit();
        }
        if (noise) {
            AtomicTextFile noise_file(s.noise_model);
            JsonlWriter(noise_file.stream(), s.noise_model).write(noise->to_json());
            noise_file.commit();
            log.info("sky noise: rms ", noise->rms, " (MAD σ ", noise->mad_sigma, ") over ",
                     noise->pixels, " pixels; autocorrelation at (1,0) ",
                     noise->correlation.at(1, 0), ", (1,1) ", noise->correlation.at(1, 1),
                     ", (2,0) ", noise->correlation.at(2, 0));
        }
        if (stamps) stamps->commit();
        if (stars_file) stars_file->commit();
        file.commit();
        written = out.count();
    }
    log.info(written, " galaxies, ", tally.stars, " stars (stellarity > ",
             s.detection.star_threshold, ", through ", locus_note, ") in ", log.elapsed(),
             " s (peak memory ", std::lround(log.peak_memory_mib()), " MiB)");
    if (tally.saturated > 0)
        log.info(tally.saturated, " saturated objects (a pixel at or above ",
                 s.detection.detection.saturation, ") set aside with the stars");
    if (tally.single_pixel_events > 0)
        log.info(tally.single_pixel_events, " single-pixel events (cosmic rays, hot pixels: ",
                 "the peak holds ≥ 75% of the flux) left out");
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "shapesim-detect", run); }
