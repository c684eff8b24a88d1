#include "decompose/options.hpp"

#include "shapesim/analytic_psf.hpp"
#include "shapesim/error.hpp"

#include "shapesim/atomic_file.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/geometry.hpp"
#include "shapesim/noise.hpp"
#include "shapesim/psf.hpp"

#include <optional>
#include <utility>

namespace shapesim::app {

// One table, long because decompose has many options: split, it would read as fragments of
// the --help it prints, in that order.
void DecomposeSettings::declare(ProgramOptions& options) {
    DecomposeSettings& s = *this;
    DecomposeOptions& f = s.fit;
    options.group("Input").add_options()
        ("input,i", po::value(&s.input)->value_name("FILE")->default_value("-"),
         "source records, or the first argument (default: stdin)")
        ("stamps", po::value(&s.stamps)->value_name("FILE"),
         "stamps file (default: each record's stamp_file)")
        ("stars", po::value(&s.stars)->value_name("FILE"),
         "star records (shapesim-detect --stars): flag galaxies whose model reaches a "
         "brighter star's wings \"bright_star\"")
        ("psf", po::value(&s.psf)->value_name("FILE"),
         "fit each galaxy's intrinsic model through this PSF (a record of the PSF mode below; "
         "forward modelling): the records are marked \"frame\": \"intrinsic\" and "
         "shapesim-render convolves them with its --psf")
        ("psf-field", po::value(&s.psf_field)->value_name("FILE"),
         "as --psf, through a PSF that varies across the image: PSFEx's model of it (psfex's "
         ".psf, in the image's pixels), taken at each source's place")
        ("real-galaxy-catalog", po::value(&s.real_galaxy_catalog)->value_name("FILE"),
         "fit every galaxy of this GalSim RealGalaxyCatalog (the COSMOS training samples' "
         "FITS table) through its own PSF image instead of reading sources; intrinsic models, "
         "the catalogue's MAG their magnitude and the catalogue their \"image\"")
        ("real-galaxy-folder", po::value(&s.real_galaxy_folder)->value_name("DIR"),
         "folder of the catalogue's galaxy and PSF files (default: the catalogue's)")
        ("real-galaxy-psf", po::value(&s.real_galaxy_psf)->value_name("IMAGE[HDU]"),
         "with --real-galaxy-catalog: the PSF image of every galaxy whose PSF file is absent "
         "(a COSMOS sample copied without it), e.g. one real ACS PSF; those records are "
         "flagged psf_substituted and name it in \"psf_image\" (default: refused)")
        ("gain", po::value(&s.gain)->value_name("E_PER_UNIT")
             ->notifier(in_range("gain", 0.0, 1e30)),
         "with --real-galaxy-catalog: electrons per image unit of its stamps (their exposure "
         "for e-/s images), for each galaxy's own photon noise (default 0: the catalogue's "
         "NOISE_VARIANCE only)")
        ("batch", po::value(&s.batch)->default_value(256)
             ->notifier(in_range("batch", 1, 1000000)),
         "with --real-galaxy-catalog: galaxies read and fitted at a time (memory bound)");
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
         "smallest scale beta/sqrt(n_max+1) the data may resolve, pixels (through --psf: of "
         "the model as seen, sqrt(beta^2 + psf sigma^2))")
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
         "keep n_max 0 fits round (the paper's); by default a sheared Gaussian replaces them,\n"
         "its best-fit shear less the noise's share in quadrature (flag elliptical)");
    options.group("PSF mode").add_options()
        ("psf-image", po::value(&s.psf_image)->value_name("FILE"),
         "model this PSF image instead of reading sources")
        ("psf-analytic", po::value(&s.psf_analytic)->value_name("SPEC"),
         "model this analytic PSF instead: gaussian:FWHM, moffat:FWHM[,BETA] (beta 3.5) or "
         "airy:LAMBDA_OVER_D[,OBSCURATION], arcsec, optionally ;jitter=SIGMA; its FWHM and "
         "encircled energies within --psf-tolerance")
        ("psf-tolerance", po::value(&s.psf_tolerance)->default_value(0.01)
             ->notifier(in_range("psf-tolerance", 1e-6, 1.0)),
         "--psf-analytic: the largest error of the model's FWHM (relative) and encircled "
         "energy within 1 and 2 FWHM (fraction of the flux)")
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
             ->notifier(in_range("psf-stamp", 5, 1001)),
         "PSF stamp side at the target scale, pixels")
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
    options.positional("input", 1);
}

void DecomposeSettings::check() {
    fit.elliptical = !round_lowest;
    if (fit.n_max_min > fit.n_max_cap) throw po::error("--n-max-min must not exceed --n-max-cap");
    fit.validate();
    if (!ids.empty() && models.empty()) throw po::error("--ids needs --models");
    if (ignore_correlation && (!noise_model.empty() || !band_noise_models.empty()))
        throw po::error("--white-noise and a noise model exclude each other");
    if (!models.empty()) check_writable(models);
    if (!psf_analytic.empty()) {
        try {
            parse_analytic_psf(psf_analytic);
        } catch (const Error& e) {
            throw po::error("--psf-analytic: " + e.message());
        }
    }
    if (!psf_field.empty() && (!psf.empty() || !psf_image.empty() || !psf_analytic.empty() ||
                               !real_galaxy_catalog.empty()))
        throw po::error("--psf-field is the PSF: not with --psf, --psf-image, --psf-analytic or "
                        "--real-galaxy-catalog");
    if (!psf_analytic.empty() && !psf_image.empty())
        throw po::error("--psf-analytic and --psf-image exclude each other");
    if (!real_galaxy_catalog.empty() && !psf_image.empty())
        throw po::error("--real-galaxy-catalog and --psf-image exclude each other");
    if (!real_galaxy_catalog.empty() && (!psf.empty() || !stamps.empty()))
        throw po::error("--real-galaxy-catalog names each galaxy's stamp and PSF: no --psf or "
                        "--stamps with it");
    if ((!real_galaxy_folder.empty() || !real_galaxy_psf.empty() || gain > 0.0) &&
        real_galaxy_catalog.empty())
        throw po::error("--real-galaxy-folder, --real-galaxy-psf and --gain need "
                        "--real-galaxy-catalog");
}

JobReader DecomposeSettings::job_reader(const ProgramOptions& options) {
    JobSettings settings;
    settings.stamps = stamps;
    settings.reference_band = reference_band;
    settings.bands = !no_bands;
    if (options.given("noise-correlation")) settings.noise_correlation = noise_correlation;
    settings.white_noise = ignore_correlation;
    // Named inputs are opened before any record is read: a missing file is an error even when
    // there is nothing to fit. The PSFs are read in arcsec (pixel scale 1) and dilated (flux
    // kept) to each record's pixel scale.
    JobReader reader(std::move(settings));
    if (!psf.empty()) reader.set_psf(read_psf_model(psf, 1.0));
    if (!psf_field.empty())
        reader.set_psf_field(std::make_shared<const PsfField>(read_psf_field(psf_field)));
    for (const auto& [band, file] : named_files(band_psfs, "band-psf"))
        reader.add_band_psf(band, read_psf_model(file, 1.0));
    // Measured noise correlations: the exact take-up replaces p·F² (decompose.hpp).
    if (!noise_model.empty()) fit.correlation = read_noise_record(noise_model).correlation;
    for (const auto& [band, file] : named_files(band_noise_models, "band-noise-model"))
        reader.add_band_correlation(band, read_noise_record(file).correlation);
    return reader;
}

double DecomposeSettings::psf_target_scale(const ProgramOptions& options) const {
    if (options.given("pixel-scale")) return pixel_scale;
    if (options.common().like.empty())
        throw po::error("PSF mode needs --like IMAGE or --pixel-scale");
    return read_field_geometry(options.common().like).pixel_scale;
}

PsfFitOptions DecomposeSettings::psf_fit() const {
    PsfFitOptions fit;
    fit.residual_target = psf_residual;
    fit.n_max_cap = psf_n_max_cap;
    return fit;
}

}  // namespace shapesim::app
