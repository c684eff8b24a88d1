// shapesim-decompose: shapesim.source/1 records + their stamps → shapesim.shapelet/1 models
// with optimised centre, β and n_max (paper §2.2; DESIGN §1–3). The work is in the library:
// decompose_job.hpp (each source's job), decompose.hpp (the optimiser and the record), lsq.hpp
// (the linear fit), psf.hpp (PSF mode); the options in decompose/options.hpp.
#include "shapesim/analytic_psf.hpp"
#include "decompose/options.hpp"
#include "app/options.hpp"
#include "app/progress.hpp"
#include "app/provenance.hpp"
#include "app/run_main.hpp"
#include "shapesim/atomic_file.hpp"
#include "shapesim/decompose_job.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/parallel.hpp"
#include "shapesim/polar.hpp"
#include "shapesim/psf.hpp"
#include "shapesim/real_galaxy_catalog.hpp"

#include <algorithm>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace {

using namespace shapesim;

const char* const description =
    "Fit each postage stamp with a polar shapelet series, choosing the centre (the model's\n"
    "own centroid), the scale beta (a search on chi2_r within the resolution and stamp\n"
    "limits) and n_max (raised while two more orders take up more chi2 than the noise\n"
    "would, capped at 15; converged when chi2_r <= 1). Reads shapesim.source/1\n"
    "records (stdin or FILE) and the stamps shapesim-detect wrote; writes shapesim.shapelet/1.\n"
    "\n"
    "Catalogue mode: with --real-galaxy-catalog, fit every galaxy of a GalSim\n"
    "RealGalaxyCatalog (e.g. the COSMOS training samples) through its own PSF image.\n"
    "\n"
    "PSF mode: with --psf-image, model an (oversampled) PSF image at the pixel scale of\n"
    "--like (or --pixel-scale) and write one shapesim.shapelet/1 record of unit flux;\n"
    "with --psf-analytic, a Gaussian, Moffat or Airy PSF given by its numbers.\n"
    "\n"
    "Several bands: records of shapesim-detect --bands are fitted in every band at once\n"
    "(one centre, beta and n_max; each band its coefficients), the first band (or\n"
    "--reference-band) the record's own model, every band in its \"bands\" list.\n"
    "\n"
    "Examples (after shapesim-detect ... --stamps stamps.fits > sources.jsonl):\n"
    "  shapesim-decompose --stamps stamps.fits -j 2 < sources.jsonl > shapelets.jsonl\n"
    "  shapesim-decompose --psf-image wfpc2_f814w_tinytim_psf.fits --like hdf.fits \\\n"
    "      --psf-box 0.0996 0.05 > psf.jsonl\n"
    "  shapesim-decompose --psf-analytic moffat:0.7,3.5 --pixel-scale 0.2 > seeing.jsonl\n"
    "  shapesim-decompose --real-galaxy-catalog real_galaxy_catalog_25.2.fits -j 2 \\\n"
    "      > cosmos.jsonl";

// PSF mode: one record of the PSF image's shapelet model at the target pixel scale.
// The --models file of the fits' images (none without --models).
std::unique_ptr<FitsWriter> models_file(const app::DecomposeSettings& s,
                                        const app::ProgramOptions& options) {
    if (s.models.empty()) return nullptr;
    return std::make_unique<FitsWriter>(s.models, "shapesim-decompose",
                                        app::provenance_keywords(options, {"models"}));
}

// The PSF stamp's side: --psf-stamp, made odd.
int odd_psf_stamp(const app::DecomposeSettings& s) {
    return s.psf_stamp % 2 == 1 ? s.psf_stamp : s.psf_stamp + 1;
}

// PSF mode, analytic: the profile's shapelet model at the target pixel scale, its FWHM and
// encircled energies checked against the profile (analytic_psf.hpp).
int run_analytic_psf(const app::DecomposeSettings& s, const app::ProgramOptions& options,
                     const app::Log& log, AtomicTextFile& file) {
    const double target = s.psf_target_scale(options);
    const AnalyticPsf profile = parse_analytic_psf(s.psf_analytic);
    PsfFitOptions fit = analytic_psf_fit();
    if (options.given("psf-residual")) fit.residual_target = s.psf_residual;
    if (options.given("psf-n-max-cap")) fit.n_max_cap = s.psf_n_max_cap;
    const AnalyticPsfModel m = analytic_psf_model(profile, target, fit, s.psf_tolerance);
    ShapeletRecord r = psf_record(m.psf, target, "psf");
    r.extra["analytic"] = profile.describe();
    r.extra["psf_fwhm"] = m.fwhm;
    r.extra["psf_fwhm_error"] = m.fwhm_error;
    r.extra["psf_ee_error"] = Json::array({m.ee_error_1, m.ee_error_2});
    r.extra["psf_profile_flux_outside"] = m.flux_outside;
    if (m.worst_error() > s.psf_tolerance) r.flags.push_back("above_tolerance");
    JsonlWriter(file.stream(), file.name()).write(r.to_json());
    file.commit();
    log.info("PSF ", profile.describe(), " at ", target, "\"/px: n_max ", m.psf.n_max, ", beta ",
             m.psf.model.beta_pix * target, "\"; FWHM ", m.fwhm, "\" (model ",
             100 * m.fwhm_error, "%), encircled energy within 1 and 2 FWHM off by ",
             100 * m.ee_error_1, "% and ", 100 * m.ee_error_2, "% of the flux; ",
             100 * m.flux_outside, "% of the profile's light beyond the ", m.stamp,
             "-pixel stamp (", log.elapsed(), " s)");
    if (m.worst_error() > s.psf_tolerance)
        log.warn("the PSF model misses --psf-tolerance ", s.psf_tolerance, " (worst error ",
                 m.worst_error(), " at n_max ", m.psf.n_max,
                 "); the record is flagged above_tolerance");
    return 0;
}

int run_psf(const app::DecomposeSettings& s, const app::ProgramOptions& options,
            const app::Log& log, AtomicTextFile& file) {
    const double target = s.psf_target_scale(options);
    const PsfImage image = read_psf_image(
        s.psf_image,
        options.given("psf-pixel-scale") ? std::optional(s.psf_pixel_scale) : std::nullopt);
    const int side = odd_psf_stamp(s);
    const PsfModel psf =
        psf_from_oversampled(image.pixels, image.pixel_scale, target, s.psf_box, side, s.psf_fit());
    JsonlWriter(file.stream(), file.name()).write(psf_record(psf, target, "psf").to_json());
    log.info("PSF n_max ", psf.n_max, ", beta ", psf.model.beta_pix * target, "\" (",
             psf.model.beta_pix, " px): max |residual| ", psf.max_residual_fraction,
             " of the peak, rms ", psf.rms_residual_fraction, "; sky ", image.sky,
             " subtracted (", log.elapsed(), " s)");
    if (!psf.reached_target)
        log.warn("the PSF model misses its residual target: max |residual| ",
                 psf.max_residual_fraction, " of the peak > --psf-residual ", s.psf_residual,
                 " at n_max ", psf.n_max, " (--psf-n-max-cap ", s.psf_n_max_cap,
                 "); the record is flagged residual_above_target");
    if (!s.models.empty()) {
        FitsWriter models(s.models, "shapesim-decompose",
                          app::provenance_keywords(options, {"models"}));
        models.write_image(psf.image, {"psf.data", -64, {}, {}, {}, {}});
        models.write_image(psf.image - psf.residual, {"psf.model", -64, {}, {}, {}, {}});
        models.write_image(psf.residual, {"psf.residual", -64, {}, {}, {}, {}});
        models.commit();
    }
    file.commit();
    return 0;
}

// Catalogue mode: every galaxy of a RealGalaxyCatalog fitted through its own PSF image,
// `--batch` galaxies read at a time (stamps and PSF images on this thread, the PSF and galaxy
// fits in parallel) and written in the catalogue's order: memory stays bounded by the batch,
// and the output does not depend on the thread count or the batch.
int run_catalogue(const app::DecomposeSettings& s, const app::ProgramOptions& options,
                  const app::Log& log, AtomicTextFile& file) {
    const std::string& catalogue = s.real_galaxy_catalog;
    std::vector<RealGalaxy> galaxies = read_real_galaxy_catalog(catalogue, s.real_galaxy_folder);
    log.info(galaxies.size(), " galaxies in ", catalogue, " (", log.elapsed(), " s)");
    // A PSF file the catalogue names but that is not here: refused before any fit, with the way
    // out, or every such galaxy through the stated substitute.
    if (const std::vector<std::size_t> absent = absent_psf_files(galaxies); !absent.empty()) {
        const RealGalaxy& first = galaxies[absent.front()];
        if (s.real_galaxy_psf.empty())
            throw Error(first.psf + ": no such file (the catalogue's PSF file is not here: "
                                    "give one with --real-galaxy-psf IMAGE[HDU])",
                        catalogue, first.row, "PSF_FILENAME");
        log.warn(absent.size(), " of ", galaxies.size(), " galaxies' PSF files are absent (first: ",
                 first.ident, "): fitted through --real-galaxy-psf ", s.real_galaxy_psf,
                 " instead (flagged psf_substituted)");
        for (std::size_t k : absent) {
            galaxies[k].psf = s.real_galaxy_psf;
            galaxies[k].psf_substituted = true;
        }
    }
    const int side = odd_psf_stamp(s);
    const std::unique_ptr<FitsWriter> models = models_file(s, options);
    const std::vector<std::string> listed = app::split_list(s.ids);
    JsonlWriter out(file.stream(), file.name());
    app::Progress progress(log, "fitted", "galaxies", galaxies.size());
    long converged = 0, failed = 0, psf_missed = 0;
    for (std::size_t start = 0; start < galaxies.size(); start += std::size_t(s.batch)) {
        const std::size_t n = std::min(std::size_t(s.batch), galaxies.size() - start);
        std::vector<DecomposeJob> jobs;
        std::vector<PsfImage> psf_images;
        for (std::size_t k = 0; k < n; ++k) {
            const RealGalaxy& g = galaxies[start + k];
            DecomposeJob job = real_galaxy_job(g, catalogue, s.gain);
            if (options.given("noise-correlation")) job.noise_correlation = s.noise_correlation;
            else if (s.ignore_correlation) job.noise_correlation = 1.0;
            jobs.push_back(std::move(job));
            psf_images.push_back(read_real_galaxy_psf(g, catalogue));
        }
        std::vector<std::optional<PsfModel>> psfs(n);
        std::vector<DecomposeOutcome> outcomes(n);
        parallel_for(n, options.common().threads, [&](std::size_t k, int) {
            try {
                psfs[k] = real_galaxy_psf(psf_images[k], jobs[k].pixel_scale, side, s.psf_fit());
                jobs[k].psf = to_cartesian(psfs[k]->model);
                outcomes[k] = decompose_job(jobs[k], s.fit, {});
            } catch (const Error& e) {  // the PSF image's: the galaxy cannot be fitted
                outcomes[k].error = "its PSF " + galaxies[start + k].psf + ": " + e.message();
            }
            progress.done_one();
        });
        for (std::size_t k = 0; k < n; ++k) {
            const RealGalaxy& g = galaxies[start + k];
            DecomposeOutcome& o = outcomes[k];
            if (!o.record) {
                ++failed;
                log.warn("galaxy ", g.ident, " (", catalogue, ": row ", g.row, "): ", o.error);
                continue;
            }
            ShapeletRecord& r = *o.record;
            r.mag = g.mag;  // the catalogue's: what its sample was selected on
            r.extra["psf_n_max"] = psfs[k]->n_max;
            if (g.psf_substituted) {
                r.flags.push_back("psf_substituted");
                r.extra["psf_image"] = g.psf;
            }
            r.extra["psf_residual"] = psfs[k]->max_residual_fraction;
            if (!psfs[k]->reached_target) {
                ++psf_missed;
                r.flags.push_back("psf_residual_above_target");
            }
            if (std::find(r.flags.begin(), r.flags.end(), "converged") != r.flags.end())
                ++converged;
            out.write(r.to_json());
            log.verbose("galaxy ", g.ident, ": n_max ", r.n_max, " chi2r ", *r.chi2r, " (",
                        o.decomposition->stop, "); PSF n_max ", psfs[k]->n_max);
            if (models && (listed.empty() || std::count(listed.begin(), listed.end(), g.ident)))
                write_fit_images(*models, jobs[k], o.decomposition->fit);
        }
    }
    if (models) models->commit();
    file.commit();
    if (psf_missed > 0)
        log.warn(psf_missed, " PSF models miss --psf-residual ", s.psf_residual,
                 " (flagged psf_residual_above_target)");
    log.info(out.count(), " models (", converged, " converged: chi2_r <= ", s.fit.chi2_target,
             " within ", s.fit.chi2_sigmas, " sigma), ", failed, " galaxies not fitted, in ",
             log.elapsed(), " s");
    return 0;
}

int run(int argc, const char* const argv[]) {
    app::ProgramOptions options("shapesim-decompose", "[OPTION]... [FILE]", description,
                                app::Common::output | app::Common::quiet | app::Common::verbose |
                                    app::Common::threads | app::Common::like |
                                    app::Common::config | app::Common::print_params);
    app::DecomposeSettings s;
    s.declare(options);
    if (!options.parse(argc, argv)) return 0;
    const app::Log log("shapesim-decompose", options.common().verbosity);
    s.check();
    AtomicTextFile file(options.common().output_or_stdout());
    if (!s.psf_image.empty()) return run_psf(s, options, log, file);
    if (!s.psf_analytic.empty()) return run_analytic_psf(s, options, log, file);
    if (!s.real_galaxy_catalog.empty()) return run_catalogue(s, options, log, file);

    std::vector<SourceRecord> stars;
    if (!s.stars.empty()) {
        JsonlReader star_reader(s.stars, {SourceRecord::schema});
        SourceRecord star;
        while (star_reader.next_record(star)) stars.push_back(star);
    }
    // Read every record and its stamp first (cfitsio handles stay on this thread), fit in
    // parallel, write in input order: the output does not depend on the thread count.
    JsonlReader reader(s.input, {SourceRecord::schema});
    JobReader job_reader = s.job_reader(options);
    std::vector<DecomposeJob> jobs;
    SourceRecord source;
    while (reader.next_record(source)) jobs.push_back(job_reader.read(source, reader));
    const std::string star_count =
        s.stars.empty() ? "" : " and " + std::to_string(stars.size()) + " stars";
    log.info(jobs.size(), " stamps", star_count, " read in ", log.elapsed(), " s");

    std::vector<DecomposeOutcome> outcomes(jobs.size());
    app::Progress progress(log, "fitted", "stamps", jobs.size());
    parallel_for(jobs.size(), options.common().threads, [&](std::size_t k, int) {
        outcomes[k] = decompose_job(jobs[k], s.fit, stars);
        progress.done_one();
    });

    const std::unique_ptr<FitsWriter> models = models_file(s, options);
    const std::vector<std::string> listed = app::split_list(s.ids);
    JsonlWriter out(file.stream(), file.name());
    long converged = 0, failed = 0;
    for (std::size_t k = 0; k < jobs.size(); ++k) {
        const DecomposeJob& job = jobs[k];
        const DecomposeOutcome& o = outcomes[k];
        if (!o.record) {
            // A stamp no fit can use (all masked, too small): said on stderr and counted; the
            // run goes on, since one bad stamp must not cost a catalogue.
            ++failed;
            log.warn("object ", job.source.id, " (", reader.name(), ":", job.line, "): ", o.error);
            continue;
        }
        const std::vector<std::string>& flags = o.record->flags;
        if (std::find(flags.begin(), flags.end(), "converged") != flags.end()) ++converged;
        out.write(o.record->to_json());
        log.verbose("object ", job.source.id, ": n_max ", o.record->n_max, " chi2r ",
                    *o.record->chi2r, " (", o.decomposition->stop, ")");
        if (models && (listed.empty() || std::count(listed.begin(), listed.end(), job.source.id)))
            write_fit_images(*models, job, o.decomposition->fit);
    }
    if (models) models->commit();
    file.commit();
    log.info(out.count(), " models (", converged, " converged: chi2_r <= ", s.fit.chi2_target,
             " within ", s.fit.chi2_sigmas, " sigma), ", failed, " stamps not fitted, in ",
             log.elapsed(), " s");
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "shapesim-decompose", run); }
