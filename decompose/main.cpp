// shapesim-decompose: shapesim.source/1 records + their stamps → shapesim.shapelet/1 models
// with optimised centre, β and n_max (paper §2.2; DESIGN §1–3). The work is in the library:
// decompose.hpp (the optimiser and the record), lsq.hpp (the linear fit).
#include "shapesim/app/atomic_file.hpp"
#include "shapesim/app/options.hpp"
#include "shapesim/app/provenance.hpp"
#include "shapesim/app/progress.hpp"
#include "shapesim/app/run_main.hpp"
#include "shapesim/bands.hpp"
#include "shapesim/decompose.hpp"
#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/geometry.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/noise.hpp"
#include "shapesim/parallel.hpp"
#include "shapesim/polar.hpp"
#include "shapesim/psf.hpp"
#include "shapesim/records.hpp"
#include "shapesim/transform.hpp"

#include <exception>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <set>

namespace {

using namespace shapesim;
namespace po = app::po;

const char* const description =
    "Fit each postage stamp with a polar shapelet series, choosing the centre (the model's\n"
    "own centroid), the scale beta (a search on chi2_r within the resolution and stamp\n"
    "limits) and n_max (raised while two more orders take up more chi2 than the noise\n"
    "would, capped at 15; converged when chi2_r <= 1). Reads shapesim.source/1\n"
    "records on stdin and the stamps shapesim-detect wrote; writes shapesim.shapelet/1.\n"
    "\n"
    "PSF mode: with --psf-image, model an (oversampled) PSF image at the pixel scale of\n"
    "--like (or --pixel-scale) and write one shapesim.shapelet/1 record of unit flux.\n"
    "\n"
    "Several bands: records of shapesim-detect --bands are fitted in every band at once\n"
    "(one centre, beta and n_max; each band its coefficients), the first band (or\n"
    "--reference-band) the record's own model, every band in its \"bands\" list.\n"
    "\n"
    "Examples (after shapesim-detect ... --stamps stamps.fits > sources.jsonl):\n"
    "  shapesim-decompose --stamps stamps.fits -j 2 < sources.jsonl > shapelets.jsonl\n"
    "  shapesim-decompose --psf-image wfpc2_f814w_tinytim_psf.fits --like hdf.fits \\\n"
    "      --psf-box 0.0996 0.05 > psf.jsonl";

struct Settings {
    std::string stamps, models, ids, stars;
    std::string psf_image, psf, reference_band;
    std::vector<std::string> band_psfs, band_noise_models;
    std::string noise_model;
    bool no_bands = false;
    double psf_pixel_scale = 0.0, pixel_scale = 0.0, psf_residual = 0.01;
    std::vector<double> psf_box;
    int psf_stamp = 41, psf_n_max_cap = 20;
    std::string input = "-";
    bool ignore_correlation = false;
    bool round_lowest = false;
    double noise_correlation = 0.0;
    DecomposeOptions fit;
};

void declare(app::ProgramOptions& options, Settings& s) {
    using app::in_range;
    DecomposeOptions& f = s.fit;
    options.group("Input").add_options()
        ("input,i", po::value(&s.input)->value_name("FILE")->default_value("-"),
         "source records (default: stdin)")
        ("stamps", po::value(&s.stamps)->value_name("FILE"),
         "stamps file (default: each record's stamp_file)")
        ("stars", po::value(&s.stars)->value_name("FILE"),
         "star records (shapesim-detect --stars): flag galaxies whose model reaches a "
         "brighter star's wings \"bright_star\"")
        ("psf", po::value(&s.psf)->value_name("FILE"),
         "fit each galaxy's intrinsic model through this PSF (a record of the PSF mode below; "
         "forward modelling): the records are marked \"frame\": \"intrinsic\" and "
         "shapesim-render convolves them with its --psf");
    options.group("Bands").add_options()
        ("reference-band", po::value(&s.reference_band)->value_name("NAME"),
         "the band whose model is the record's own (default: the record's first band)")
        ("band-psf", po::value(&s.band_psfs)->value_name("NAME=FILE")->composing(),
         "fit band NAME through this PSF record instead of --psf (repeatable)")
        ("band-noise-model", po::value(&s.band_noise_models)->value_name("NAME=FILE")->composing(),
         "band NAME's sky noise record instead of --noise-model (repeatable)")
        ("no-bands", po::bool_switch(&s.no_bands),
         "fit only the detection image's stamp, even when records carry bands");
    options.group("Optimiser").add_options()
        ("n-max-cap", po::value(&f.n_max_cap)->default_value(15)
             ->notifier(in_range("n-max-cap", 0, 100)), "highest n_max")
        ("n-max-min", po::value(&f.n_max_min)->default_value(0)
             ->notifier(in_range("n-max-min", 0, 100)), "first n_max tried")
        ("chi2-target", po::value(&f.chi2_target)->default_value(1.0)
             ->notifier(in_range("chi2-target", 1e-6, 1e6)), "stop when chi2_r reaches this")
        ("chi2-sigmas", po::value(&f.chi2_sigmas)->default_value(2.0)
             ->notifier(in_range("chi2-sigmas", 0.0, 100.0)),
         "accept chi2_r up to the target plus this many sigma of its noise, sqrt(2/dof)")
        ("beta-tolerance", po::value(&f.beta_tolerance)->default_value(1e-3)
             ->notifier(in_range("beta-tolerance", 1e-8, 0.5)),
         "tolerance of the beta search, in ln beta")
        ("theta-min", po::value(&f.theta_min)->default_value(1.0)
             ->notifier(in_range("theta-min", 1e-3, 1e3)),
         "smallest scale beta/sqrt(n_max+1) the basis may resolve, pixels")
        ("order-sigmas", po::value(&f.order_sigmas)->default_value(3.0)
             ->notifier(in_range("order-sigmas", 0.0, 1e3)),
         "raise n_max while two more orders lower chi2 by more than the noise's take-up "
         "F^2 (dp + this * sqrt(2 dp))")
        ("bad-fit-chi2r", po::value(&f.bad_fit_chi2r)->default_value(1.5)
             ->notifier(in_range("bad-fit-chi2r", 1e-3, 1e6)),
         "flag fits kept with chi2_r above this bad_fit")
        ("max-hole", po::value(&f.max_hole)->default_value(0.1)
             ->notifier(in_range("max-hole", 0.0, 1e6)),
         "flag holes a model dipping below zero by more than this fraction of its peak, or "
         "with more than this fraction of its light below zero (an intrinsic model as seen "
         "through its PSF)")
        ("max-unsupported", po::value(&f.max_unsupported)->default_value(0.2)
             ->notifier(in_range("max-unsupported", 0.0, 1.0)),
         "flag unsupported a model with more than this fraction of its light where no datum "
         "constrains it (outside the stamp, on a neighbour's pixels, at zero weight)")
        ("noise-correlation", po::value(&s.noise_correlation)->value_name("F")
             ->notifier(in_range("noise-correlation", 1.0, 100.0)),
         "correlated-noise factor for the effective degrees of freedom (default: the "
         "record's noise_correlation from shapesim-detect, else 1)")
        ("noise-model", po::value(&s.noise_model)->value_name("FILE"),
         "the image's sky noise record (shapesim-detect --noise-model): its measured "
         "correlation gives each fit's exact noise take-up (degrees of freedom, order test) "
         "instead of F^2 per coefficient")
        ("white-noise", po::bool_switch(&s.ignore_correlation),
         "use the textbook chi2_r (F = 1) even when the record has a factor")
        ("round-lowest", po::bool_switch(&s.round_lowest),
         "keep n_max 0 fits round (the paper's); by default a sheared Gaussian replaces them\n"
         "when its ellipticity is significant (flag elliptical)");
    options.group("PSF mode").add_options()
        ("psf-image", po::value(&s.psf_image)->value_name("FILE"),
         "model this PSF image instead of reading sources")
        ("psf-pixel-scale", po::value(&s.psf_pixel_scale)->value_name("ARCSEC")
             ->notifier(in_range("psf-pixel-scale", 1e-6, 3600.0)),
         "pixel scale of --psf-image (default: its PIXSCALE keyword, else its WCS)")
        ("pixel-scale", po::value(&s.pixel_scale)->value_name("ARCSEC")
             ->notifier(in_range("pixel-scale", 1e-6, 3600.0)),
         "target pixel scale (default: that of --like)")
        ("psf-box", po::value(&s.psf_box)->value_name("ARCSEC")->multitoken(),
         "convolve the PSF with square boxes of these widths first (detector pixel, drizzle "
         "drop: a subsampled TinyTim PSF lacks both)")
        ("psf-stamp", po::value(&s.psf_stamp)->default_value(41)
             ->notifier(in_range("psf-stamp", 5, 1001)), "PSF stamp side at the target scale, pixels")
        ("psf-residual", po::value(&s.psf_residual)->default_value(0.01)
             ->notifier(in_range("psf-residual", 1e-6, 1.0)),
         "raise n_max until max |residual| is below this fraction of the peak")
        ("psf-n-max-cap", po::value(&s.psf_n_max_cap)->default_value(20)
             ->notifier(in_range("psf-n-max-cap", 0, 60)), "highest n_max for the PSF");
    options.group("Output").add_options()
        ("models", po::value(&s.models)->value_name("FILE"),
         "write data, model and residual images (<id>.data/.model/.residual) to this FITS file")
        ("ids", po::value(&s.ids)->value_name("LIST"),
         "with --models: only these ids (comma-separated; default all)");
}

// NAME=FILE of a repeatable per-band option.
std::pair<std::string, std::string> name_and_file(const std::string& item, const char* option) {
    const auto eq = item.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == item.size())
        throw po::error(std::string(option) + " wants NAME=FILE, got \"" + item + "\"");
    return {item.substr(0, eq), item.substr(eq + 1)};
}

struct Job {
    SourceRecord source;
    Stamp stamp;
    double pixel_scale = 0.0;
    std::optional<double> zero_point;  // absent or null: no magnitudes
    double noise_correlation = 1.0;
    long line = 0;
    std::optional<CartesianModel> psf;  // --psf at this record's pixel scale
    JointStamps joint;                  // several bands: the reference band first
};

struct Outcome {
    std::optional<ShapeletRecord> record;
    std::optional<Decomposition> decomposition;
    std::string error;  // non-empty: the stamp could not be fitted at all
};

// PSF mode: one record of the PSF image's shapelet model at the target pixel scale.
int run_psf(const Settings& s, const app::ProgramOptions& options, const app::Log& log) {
    double target = s.pixel_scale;
    if (!options.given("pixel-scale")) {
        if (options.common().like.empty())
            throw po::error("PSF mode needs --like IMAGE or --pixel-scale");
        target = read_field_geometry(options.common().like).pixel_scale;
    }
    const PsfImage image = read_psf_image(
        s.psf_image,
        options.given("psf-pixel-scale") ? std::optional(s.psf_pixel_scale) : std::nullopt);
    PsfFitOptions fit;
    fit.residual_target = s.psf_residual;
    fit.n_max_cap = s.psf_n_max_cap;
    const int side = s.psf_stamp % 2 == 1 ? s.psf_stamp : s.psf_stamp + 1;
    const PsfModel psf =
        psf_from_oversampled(image.pixels, image.pixel_scale, target, s.psf_box, side, fit);
    JsonlWriter out(std::cout, "-");
    out.write(psf_record(psf, target, "psf").to_json());
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
    return 0;
}

int run(int argc, const char* const argv[]) {
    app::ProgramOptions options("shapesim-decompose", "[OPTION]...", description,
                                app::Common::quiet | app::Common::verbose | app::Common::threads |
                                    app::Common::like | app::Common::config |
                                    app::Common::print_params);
    Settings s;
    declare(options, s);
    if (!options.parse(argc, argv)) return 0;
    s.fit.elliptical = !s.round_lowest;
    const app::Log log("shapesim-decompose", options.common().verbosity);
    if (s.fit.n_max_min > s.fit.n_max_cap)
        throw po::error("--n-max-min must not exceed --n-max-cap");
    s.fit.validate();
    if (!s.ids.empty() && s.models.empty()) throw po::error("--ids needs --models");
    if (s.ignore_correlation && (!s.noise_model.empty() || !s.band_noise_models.empty()))
        throw po::error("--white-noise and a noise model exclude each other");
    if (!s.models.empty()) app::check_writable(s.models);
    if (!s.psf_image.empty()) return run_psf(s, options, log);

    std::vector<SourceRecord> stars;
    if (!s.stars.empty()) {
        JsonlReader star_reader(s.stars, {SourceRecord::schema});
        SourceRecord star;
        while (star_reader.next_record(star)) stars.push_back(star);
    }
    // Read every record and its stamp first (cfitsio handles stay on this thread), fit in
    // parallel, write in input order: the output does not depend on the thread count.
    JsonlReader reader(s.input, {SourceRecord::schema});
    StampFiles stamp_files;
    std::vector<Job> jobs;
    // Named inputs are opened before any record is read: a missing file is an error even when
    // there is nothing to fit. The PSF is read once, in arcsec (pixel scale 1), and dilated
    // (flux kept) to each record's pixel scale.
    if (!s.stamps.empty()) stamp_files[s.stamps] = std::make_unique<FitsReader>(s.stamps);
    std::optional<ShapeletModel> psf_arcsec;
    if (!s.psf.empty()) psf_arcsec = read_psf_model(s.psf, 1.0);
    std::map<double, CartesianModel> psfs;  // by pixel scale
    std::map<std::string, ShapeletModel> band_psfs;  // --band-psf, arcsec
    std::map<std::pair<std::string, double>, CartesianModel> band_psfs_at;  // by pixel scale
    for (const std::string& item : s.band_psfs) {
        const auto [band, file] = name_and_file(item, "--band-psf");
        band_psfs[band] = read_psf_model(file, 1.0);
    }
    // Measured noise correlations: the exact take-up replaces p·F² (decompose.hpp).
    if (!s.noise_model.empty()) s.fit.correlation = read_noise_record(s.noise_model).correlation;
    std::map<std::string, NoiseCorrelation> band_correlations;  // --band-noise-model
    for (const std::string& item : s.band_noise_models) {
        const auto [band, file] = name_and_file(item, "--band-noise-model");
        band_correlations[band] = read_noise_record(file).correlation;
    }
    SourceRecord source;
    // Field errors from the record's extra fields, placed at the reader's file and line.
    const auto placed = [&](const auto& read) {
        try {
            return read();
        } catch (const Error& e) {
            throw reader.locate(e);
        }
    };
    while (reader.next_record(source)) {
        Job job;
        job.line = reader.line();
        std::string file = s.stamps;
        if (file.empty()) {
            if (!source.extra.contains("stamp_file"))
                throw Error("no stamp_file in the record: give --stamps", reader.name(),
                            reader.line(), "stamp_file");
            file = placed([&] { return required_string(source.extra, "stamp_file"); });
        }
        std::string hdu = source.id;
        if (source.extra.contains("stamp_hdu"))
            hdu = placed([&] { return required_string(source.extra, "stamp_hdu"); });
        auto& fits = stamp_files[file];
        if (!fits) fits = std::make_unique<FitsReader>(file);
        try {
            job.stamp = read_stamp(*fits, hdu);
        } catch (const Error& e) {  // the FITS place and the record that asked for it
            throw Error(e.where_what(), reader.name(), reader.line(), "stamp_hdu");
        }
        if (options.given("noise-correlation"))
            job.noise_correlation = s.noise_correlation;
        else if (!s.ignore_correlation && source.extra.contains("noise_correlation"))
            job.noise_correlation = std::max(1.0, placed([&] {
                return required_double(source.extra, "noise_correlation");
            }));
        // Typed reads here, on the reading thread: a wrong type is a placed error, not a
        // worker's exception.
        job.pixel_scale = placed([&] {
            const auto v = optional_double(source.extra, "pixel_scale");
            if (!v || !(*v > 0.0))
                throw Error("no positive pixel_scale in the record", "", 0, "pixel_scale");
            return *v;
        });
        job.zero_point = placed([&] { return optional_double(source.extra, "zero_point"); });
        if (psf_arcsec) {
            auto at_scale = psfs.find(job.pixel_scale);
            if (at_scale == psfs.end())
                at_scale = psfs.emplace(job.pixel_scale,
                                        to_cartesian(dilate(*psf_arcsec, 1.0 / job.pixel_scale)))
                               .first;
            job.psf = at_scale->second;
        }
        if (!s.no_bands) {
            // A --band-psf at this record's pixel scale, dilated once per scale (as --psf).
            const auto psf_of = [&](const std::string& band) -> std::optional<CartesianModel> {
                const auto own = band_psfs.find(band);
                if (own == band_psfs.end()) return job.psf;
                auto at = band_psfs_at.find({band, job.pixel_scale});
                if (at == band_psfs_at.end())
                    at = band_psfs_at
                             .emplace(std::pair(band, job.pixel_scale),
                                      to_cartesian(dilate(own->second, 1.0 / job.pixel_scale)))
                             .first;
                return at->second;
            };
            job.joint = placed([&] {
                std::vector<SourceBand> bands = source_bands(source);
                if (bands.empty()) return JointStamps{};
                return read_joint_stamps(std::move(bands), job.stamp, file, s.stamps,
                                         s.reference_band, stamp_files, psf_of);
            });
            for (const SourceBand& band : job.joint.bands) {
                const auto own = band_correlations.find(band.band);
                job.joint.correlations.push_back(
                    own != band_correlations.end() ? std::optional(own->second) : std::nullopt);
            }
        }
        job.source = source;
        jobs.push_back(std::move(job));
    }
    log.info(jobs.size(), " stamps", s.stars.empty() ? "" : " and " + std::to_string(stars.size()) + " stars",
             " read in ", log.elapsed(), " s");

    std::vector<Outcome> outcomes(jobs.size());
    app::Progress progress(log, "fitted", "stamps", jobs.size());
    parallel_for(jobs.size(), options.common().threads, [&](std::size_t k, int) {
        const Job& job = jobs[k];
        Outcome& out = outcomes[k];
        try {
            DecomposeOptions fit = s.fit;
            fit.noise_correlation = job.noise_correlation;
            fit.psf = job.psf;
            MaskArray mask = (job.stamp.mask != 0.0).cast<std::uint8_t>();
            const double x = job.source.x - (job.stamp.x0 - 1);
            const double y = job.source.y - (job.stamp.y0 - 1);
            const double beta = std::max(job.source.a.value_or(1.0), 0.5);
            if (job.joint.bands.empty()) {
                out.decomposition = decompose(job.stamp.image, job.stamp.weight, &mask, x, y,
                                              beta, fit);
                out.record = shapelet_record(job.source, *out.decomposition, job.stamp,
                                             job.pixel_scale, job.zero_point,
                                             job.psf ? &*job.psf : nullptr);
            } else {  // --noise-correlation and --white-noise hold for every band
                const std::optional<double> F =
                    options.given("noise-correlation") ? std::optional(s.noise_correlation)
                    : s.ignore_correlation             ? std::optional(1.0)
                                                       : std::nullopt;
                auto [d, r] = decompose_joint(job.source, job.joint, job.stamp, x, y, beta, fit,
                                              job.pixel_scale, F);
                out.decomposition = std::move(d);
                out.record = std::move(r);
            }
            const ShapeletModel& m = out.decomposition->fit.model;
            if (near_bright_star(out.record->x, out.record->y,
                                 m.beta_pix * std::sqrt(m.n_max + 1.0), job.source.flux,
                                 stars))
                out.record->flags.push_back("bright_star");
        } catch (const Error& e) {
            out.error = e.message();
        } catch (const std::exception& e) {
            // Never let a worker's exception terminate the program.
            out.error = std::string("internal error: ") + e.what();
        }
        progress.done_one();
    });

    std::unique_ptr<FitsWriter> models;
    if (!s.models.empty()) models = std::make_unique<FitsWriter>(s.models, "shapesim-decompose");
    const std::vector<std::string> listed = app::split_list(s.ids);
    const std::set<std::string> wanted(listed.begin(), listed.end());
    JsonlWriter out(std::cout, "-");
    long converged = 0, failed = 0;
    for (std::size_t k = 0; k < jobs.size(); ++k) {
        const Job& job = jobs[k];
        const Outcome& o = outcomes[k];
        if (!o.record) {
            // A stamp no fit can use (all masked, too small): said on stderr and counted; the
            // run goes on, since one bad stamp must not cost a catalogue.
            ++failed;
            log.warn("object ", job.source.id, " (", reader.name(), ":", job.line,
                     "): ", o.error);
            continue;
        }
        if (std::find(o.record->flags.begin(), o.record->flags.end(), "converged") !=
            o.record->flags.end())
            ++converged;
        out.write(o.record->to_json());
        log.verbose("object ", job.source.id, ": n_max ", o.record->n_max, " chi2r ",
                    *o.record->chi2r, " (", o.decomposition->stop, ")");
        if (models && (wanted.empty() || wanted.count(job.source.id))) {
            const ShapeletFit& fit = o.decomposition->fit;
            const std::vector<FitsKeyword> where{FitsKeyword("LTV1", 1 - job.stamp.x0),
                                                 FitsKeyword("LTV2", 1 - job.stamp.y0)};
            // A joint fit's model is the reference band's: its data beside it.
            const ImageArray& data =
                job.joint.stamps.empty() ? job.stamp.image : job.joint.stamps.front().image;
            models->write_image(data, {job.source.id + ".data", -32, {}, {}, where, {}});
            models->write_image(fit.model_image,
                                {job.source.id + ".model", -32, {}, {}, where, {}});
            models->write_image(fit.residual,
                                {job.source.id + ".residual", -32, {}, {}, where, {}});
        }
    }
    if (models) models->commit();
    log.info(out.count(), " models (", converged, " converged: chi2_r <= ", s.fit.chi2_target,
             " within ", s.fit.chi2_sigmas, " sigma), ", failed, " stamps not fitted, in ",
             log.elapsed(), " s");
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "shapesim-decompose", run); }
