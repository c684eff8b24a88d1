// shapesim-measure: the morphology diagnostics of every galaxy of an image (paper §5,
// DESIGN §5) as shapesim.morph/1 records. Detection is shapesim-detect's own
// (app/detection_run.hpp), the statistics are measure.hpp / morphometry.hpp; the comparison
// modes are measure/compare_run.hpp.
#include "shapesim/analytic_psf.hpp"
#include "measure/compare_run.hpp"
#include "app/detection_run.hpp"
#include "app/options.hpp"
#include "app/progress.hpp"
#include "app/run_main.hpp"
#include "shapesim/atomic_file.hpp"
#include "shapesim/error.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/measure.hpp"
#include "shapesim/parallel.hpp"
#include "shapesim/psf.hpp"
#include "shapesim/stellarity.hpp"

#include <cmath>

namespace {

using namespace shapesim;
namespace po = app::po;

const char* const description =
    "Detect the objects of an image exactly as shapesim-detect does and measure, per galaxy:\n"
    "Kron magnitude, FWHM, a, b, theta, e1, e2 (paper eqs. 6-7), stellarity, the Petrosian\n"
    "radius (eta = 0.2), concentration C, asymmetry A, clumpiness S (x10, Conselice 2003),\n"
    "Gini and M20, defined as statmorph defines them, with flags where a statistic is\n"
    "unreliable (small, faint, crowded, no_sky). Records go to stdout as shapesim.morph/1.\n"
    "\n"
    "With --compare NAME=FILE ... (measured catalogues; the first is the reference), write to\n"
    "-o DIR (default: compare): table.md (the paper's Table: mean and rms of C, A, S, rms e,\n"
    "median and sd of the FWHM, with bootstrap errors), distances.md (KS statistic and\n"
    "p-value, 1D Wasserstein distance of each catalogue from the first, per statistic) and, with\n"
    "gnuplot, the figures of the paper's Figs. 5-11 as PNG. With --compare-paired REAL=FILE\n"
    "NAME=FILE ... (the real image's catalogue, then its replays: shapesim-sample --replay,\n"
    "rendered and measured alike), pair every real galaxy with its model: FWHM ratios by\n"
    "magnitude, a markdown table on stdout.\n"
    "\n"
    "Examples (the shipped HDF-N data):\n"
    "  shapesim-measure hdfn_f814w_v2.fits --weight hdfn_f814w_v2_weight.fits \\\n"
    "      --zero-point 22.08 -j 2 > hdf.morph.jsonl\n"
    "  shapesim-measure --compare hdf=hdf.morph.jsonl sim=sim.morph.jsonl -o report\n"
    "  shapesim-measure --compare-paired hdf=hdf.morph.jsonl r7=replay7.morph.jsonl \\\n"
    "      r8=replay8.morph.jsonl > paired.md";

int run(int argc, const char* const argv[]) {
    app::ProgramOptions options("shapesim-measure", "[OPTION]... IMAGE", description,
                                app::Common::quiet | app::Common::verbose | app::Common::threads |
                                    app::Common::config | app::Common::print_params);
    app::DetectionSettings detection;
    MeasureOptions measure;
    app::CompareSettings compare;
    bool stars = false, no_star_profile = false, shear_estimate = false;
    std::string psf_field;
    double mag_limit = 0.0, aperture = 0.0;
    detection.declare(options, false);
    using app::in_range;
    options.group("Statistics").add_options()
        ("with-stars", po::bool_switch(&stars),
         "also measure the stars (kind \"star\"), each with a pixel-integrated Moffat fitted "
         "(fwhm_moffat, pixels, and beta_moffat: the seeing)")
        ("no-star-profile", po::bool_switch(&no_star_profile), "no Moffat fit of the stars")
        ("aperture", po::value(&aperture)->value_name("ARCSEC")
             ->notifier(in_range("aperture", 0.0, 3600.0)),
         "also a circular aperture of this diameter about each centroid (SExtractor's "
         "MAG_APER): flux_aper and mag_aper")
        ("mag-limit", po::value(&mag_limit)->value_name("MAG")
             ->notifier(in_range("mag-limit", -100.0, 100.0)),
         "leave out objects fainter than this Kron magnitude (and those without one)")
        ("min-petrosian", po::value(&measure.min_petrosian)->default_value(2.0)
             ->notifier(in_range("min-petrosian", 0.0, 1e6)),
         "flag \"small\" below this Petrosian radius, pixels")
        ("min-snr", po::value(&measure.min_snr)->default_value(10.0)
             ->notifier(in_range("min-snr", 0.0, 1e12)), "flag \"faint\" below this Kron S/N")
        ("max-neighbour-fraction", po::value(&measure.max_neighbour_fraction)->default_value(0.1)
             ->notifier(in_range("max-neighbour-fraction", 0.0, 1.0)),
         "flag \"crowded\" above this fraction of neighbours' pixels in the CAS aperture")
        ("statmorph-boxcar", po::bool_switch(&measure.morphometry.statmorph_boxcar),
         "S with statmorph's own (even, off-centre) boxcar")
        ("shear-estimate", po::bool_switch(&shear_estimate),
         "also each galaxy's PSF-corrected shear estimate (adaptive moments, linear PSF "
         "correction; shear_e1, shear_e2, shear_resolution) through the PSF of --psf or "
         "--psf-analytic: what shapesim-calibrate takes (--e1 shear_e1 --e2 shear_e2)")
        ("psf-field", po::value(&psf_field)->value_name("FILE"),
         "the PSF varying across the image (psfex's .psf) for --shear-estimate: each galaxy "
         "is corrected by the PSF at its own place");
    compare.declare(options);
    if (!options.parse(argc, argv)) return 0;
    const app::Log log("shapesim-measure", options.common().verbosity);
    if (!compare.colours.empty()) {
        if (!detection.image.empty() || !compare.inputs.empty() || !compare.skies.empty())
            throw po::error("--compare-colours: not with an IMAGE, --compare, --compare-paired "
                            "or --compare-sky");
        AtomicTextFile file(options.common().output_or_stdout());
        compare.write_colours(file.stream(), options.given("mag-limit") ? mag_limit : 99.0,
                              options.common().threads);
        file.commit();
        return 0;
    }
    if (!compare.paired.empty()) {
        if (!detection.image.empty() || !compare.inputs.empty() || !compare.skies.empty())
            throw po::error("--compare-paired: not with an IMAGE, --compare or --compare-sky");
        AtomicTextFile file(options.common().output_or_stdout());
        compare.write_paired(file.stream());
        file.commit();
        return 0;
    }
    if (!compare.skies.empty()) {
        if (!detection.image.empty() || !compare.inputs.empty())
            throw po::error("--compare-sky: not with an IMAGE or --compare");
        AtomicTextFile file(options.common().output_or_stdout());
        compare.write_skies(file.stream());
        file.commit();
        return 0;
    }
    if (!compare.inputs.empty()) {
        if (!detection.image.empty()) throw po::error("give an IMAGE or --compare, not both");
        if (!options.common().output.empty()) compare.out = options.common().output;
        compare.write_report(log);
        return 0;
    }
    if (detection.image.empty()) throw po::error("give an IMAGE to measure (or --compare)");
    AtomicTextFile file(options.common().output_or_stdout());

    if (!psf_field.empty() && !shear_estimate)
        throw po::error("--psf-field is the PSF of --shear-estimate: give that too");
    if (shear_estimate && detection.psf_model.empty() && detection.psf_analytic.empty() &&
        psf_field.empty())
        throw po::error("--shear-estimate: give the image's PSF, --psf, --psf-analytic or "
                        "--psf-field");
    measure.fit_star_profile = !no_star_profile;
    if (!psf_field.empty()) {
        PsfField psf = read_psf_field(psf_field);
        log.verbose("shear estimate: the PSF at each galaxy's place from ", psf_field,
                    " (n_max ", psf.n_max, ", worst residual ", 100 * psf.max_residual_fraction,
                    "% of the peak)");
        measure.shear_psf_field = std::make_shared<const PsfField>(std::move(psf));
    }
    JsonlWriter out(file.stream(), file.name());
    long skipped = 0, too_faint = 0, id_offset = 0;
    std::string locus_note;
    // Each tile in turn (one, the whole image, unless tiled): its objects are measured and
    // written before the next tile is read.
    const app::TiledRun tiled = detection.run_tiles(
        options, log,
        [&](app::DetectionRun& detected, const TileWindow& tile,
            const std::vector<std::size_t>& owned) {
            const DetectionResult& field = detected.field;
            locus_note = detected.locus_note;
            if (shear_estimate && !measure.shear_psf && !measure.shear_psf_field) {
                const ShapeletModel psf =
                    !detection.psf_model.empty()
                        ? read_psf_model(detection.psf_model, detected.context.pixel_scale)
                        : analytic_psf_model(parse_analytic_psf(detection.psf_analytic),
                                             detected.context.pixel_scale).psf.model;
                measure.shear_psf = psf_adaptive_moments(psf);
                log.verbose("shear estimate: the PSF's adaptive moments (", measure.shear_psf->m11,
                            ", ", measure.shear_psf->m22, ", ", measure.shear_psf->m12,
                            ") pixels^2");
            }
            measure.zero_point = detected.context.zero_point;
            measure.aperture_radius = aperture / 2.0 / detected.context.pixel_scale;
            struct Job {
                const Detection* object;
                SourceRecord source;
                std::optional<MorphRecord> record;
                std::string error;
            };
            std::vector<Job> jobs;
            for (const std::size_t k : owned) {
                const Detection& object = field.objects[k];
                if (is_single_pixel_event(object.peak, object.flux_iso)) continue;  // a cosmic ray
                const CoreFraction core = core_fraction(field, object, detected.locus);
                const double star = stellarity(core, detected.locus);
                if (star > detection.star_threshold && !stars) continue;
                SourceRecord source = source_record(object, core, star, nullptr, detected.context);
                // Fainter than every cut of the comparison: not worth the statistics (nor a
                // record).
                if (options.given("mag-limit") && !(source.mag && *source.mag <= mag_limit)) {
                    ++too_faint;
                    continue;
                }
                jobs.push_back({&object, std::move(source), {}, {}});
            }
            app::Progress progress(log, "measured", "objects", jobs.size());
            parallel_for(jobs.size(), options.common().threads, [&](std::size_t k, int) {
                try {
                    jobs[k].record =
                        measure_object(field, *jobs[k].object, jobs[k].source, measure);
                    jobs[k].record->extra["pixel_scale"] = detected.context.pixel_scale;
                } catch (const std::exception& e) {
                    jobs[k].error = e.what();
                }
                progress.done_one();
            });
            for (const Job& job : jobs) {
                if (!job.record) {
                    ++skipped;
                    log.warn("object ", job.source.id, ": ", job.error);
                    continue;
                }
                Json record = job.record->to_json();
                app::shift_to_image(record, tile, id_offset);
                out.write(record);
            }
            id_offset += long(field.objects.size());
        });
    file.commit();
    log.info(
        out.count(), " objects measured",
        skipped ? ", " + std::to_string(skipped) + " skipped" : "",
        too_faint ? ", " + std::to_string(too_faint) + " fainter than --mag-limit left out" : "",
        tiled.tiled() ? ", in " + std::to_string(tiled.tiles.size()) + " tiles" : "", " in ",
        log.elapsed(), " s (peak memory ", std::lround(log.peak_memory_mib()), " MiB); stars (",
        stars ? "measured" : "left out", ") through ", locus_note);
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "shapesim-measure", run); }
