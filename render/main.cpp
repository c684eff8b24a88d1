// shapesim-render: shapesim.object/1 records → a FITS image with a WCS (paper §4.3;
// DESIGN §3, §6). The work is in the library: scene.hpp (reading and placing the objects,
// lensing, convolution, stamps, painting, noise, the truth), convolve.hpp, render.hpp.
#include "shapesim/analytic_psf.hpp"
#include "app/options.hpp"
#include "render/settings.hpp"
#include "app/run_main.hpp"
#include "shapesim/scene.hpp"

#include <chrono>

namespace {

using namespace shapesim;
namespace po = app::po;

const char* const description =
    "Paint objects into a FITS image as a telescope records them: each galaxy lensed (optional\n"
    "shear and convergence), convolved with the PSF in shapelet space and integrated exactly\n"
    "over the pixels it can reach; stars as the PSF; then photon noise, a (correlated)\n"
    "Gaussian background and an optional sky. Positions come from each record's ra/dec\n"
    "through the image's WCS. --tile renders a window of the field: a mosaic of tiles equals\n"
    "the whole image bit for bit, noise included.\n"
    "\n"
    "Examples:\n"
    "  shapesim-render --psf psf.jsonl --galaxy-psf psf.jsonl --like hdf.fits \\\n"
    "      --noise-like sources.jsonl --seed 7 -o sim.fits < objects.jsonl\n"
    "  shapesim-render --psf psf.jsonl --size 1 --noise-free -o clean.fits < objects.jsonl\n"
    "  shapesim-render --psf-analytic moffat:0.7,3.5 --area 25 --pixel-scale 0.2 \\\n"
    "      -o ground.fits < objects.jsonl";

int run(int argc, const char* const argv[]) {
    app::ProgramOptions options("shapesim-render", "[OPTION]... [FILE] -o IMAGE", description,
                                app::Common::quiet | app::Common::verbose |
                                    app::Common::threads | app::Common::seed | app::Common::like |
                                    app::Common::config | app::Common::print_params);
    app::RenderSettings s;
    SceneOptions& o = s.scene;
    using app::in_range;
    options.group("Input").add_options()
        ("input,i", po::value(&s.input)->value_name("FILE")->default_value("-"),
         "object records, or the first argument (default: stdin)")
        ("band", po::value(&s.band)->value_name("NAME"),
         "draw every object as it is in this band of its \"bands\" (multi-band records); the "
         "noise is this band's own realisation of --seed")
        ("psf", po::value(&s.psf)->value_name("FILE"),
         "PSF shapelet record of the image (shapesim-decompose --psf-image): stars are drawn "
         "as it, galaxies convolved with it")
        ("psf-analytic", po::value(&s.psf_analytic)->value_name("SPEC"),
         "an analytic PSF instead of --psf: gaussian:FWHM, moffat:FWHM[,BETA] or "
         "airy:LAMBDA_OVER_D[,OBSCURATION] (arcsec), optionally ;jitter=SIGMA, modelled at the "
         "image's pixel scale (shapesim-decompose --psf-analytic writes the same model)")
        ("psf-field", po::value(&s.psf_field)->value_name("FILE"),
         "a PSF that varies across the field: PSFEx's model of the image (psfex's .psf, in "
         "this field's pixels); each star is drawn as, and each galaxy convolved with, the PSF "
         "at its own place, and the truth records that PSF's shape (psf_e1, psf_e2, "
         "psf_rms_radius)")
        ("galaxy-psf", po::value(&s.galaxy_psf)->value_name("FILE"),
         "the PSF the galaxy models already hold (e.g. models of real galaxies): galaxies are "
         "convolved with the difference kernel psf / galaxy-psf, or not at all when equal")
        ("difference-order", po::value(&s.difference_order)->value_name("N"),
         "order of the difference kernel (default: the PSF's)")
        ("place-by-sky", po::bool_switch(&s.place_by_sky),
         "place objects by their ra, dec alone, even when their x, y say they were drawn for "
         "another field (by default that is an error: give render the field sample had)");
    s.field.declare(options, "Field (default: --like)",
                    "render only these field pixels (FITS, inclusive); the WCS follows");
    options.group("Accuracy").add_options()
        ("truncation", po::value(&o.truncation)->default_value(1e-3)
             ->notifier(in_range("truncation", 1e-12, 0.5)),
         "stamps end where the model is below this fraction of the noise rms (noise-free: of "
         "its central value)")
        ("shear", po::value(&s.shear)->value_name("G1 G2")->multitoken(),
         "reduced shear applied to every galaxy before the PSF")
        ("kappa", po::value(&s.kappa)->default_value(0.0)->notifier(in_range("kappa", -10.0, 0.99)),
         "convergence applied with the shear (flux kept)")
        ("lensing-tolerance", po::value(&o.lensing_tolerance)->default_value(1e-8)
             ->notifier(in_range("lensing-tolerance", 1e-14, 0.1)),
         "relative truncation of the lensed shapelet series");
    options.group("Noise").add_options()
        ("noise-rms", po::value(&o.noise_rms)->notifier(in_range("noise-rms", 0.0, 1e30)),
         "Gaussian background rms, image units")
        ("noise-correlation", po::value(&o.noise_correlation)
             ->notifier(in_range("noise-correlation", 1.0, 100.0)),
         "correlated-noise factor F of the background (drizzle-like 3x3 kernel: F up to "
         "2.34; beyond, give --noise-model)")
        ("noise-model", po::value(&s.noise_model)->value_name("FILE"),
         "the real sky's measured noise (shapesim-detect --noise-model): its rms and 2-D "
         "autocorrelation, drawn as white noise through the kernel that has it, each pixel "
         "then mapped to the sky's measured pixel distribution (its heavier tails)")
        ("gaussian-noise", po::bool_switch(&s.gaussian_noise),
         "with --noise-model: Gaussian pixels of its rms and correlation, not its measured "
         "distribution")
        ("noise-weight", po::value(&s.noise_weight)->value_name("FILE"),
         "the real field's weight map (inverse variance, the rendered field's size): the "
         "background's sigma varies over the field as 1/sqrt(weight), its mean variance kept")
        ("noise-like", po::value(&s.noise_like)->value_name("FILE"),
         "take the rms and F from shapesim-detect's records (the field's background_rms, "
         "else the median stamp noise_rms; the median noise_correlation)")
        ("gain", po::value(&o.gain)->notifier(in_range("gain", 0.0, 1e30)),
         "electrons per image unit (x --exposure) for photon noise; 0: none")
        ("exposure", po::value(&s.exposure)->default_value(1.0)
             ->notifier(in_range("exposure", 1e-9, 1e12)),
         "seconds, for images in units per second (written as EXPTIME when given)")
        ("exptime", po::value(&s.exptime)->notifier(in_range("exptime", 0.0, 1e12)),
         "the exposure time written as EXPTIME, seconds, for images in counts over the exposure "
         "(no effect on the noise; default: --exposure when given)")
        ("sky", po::value(&o.sky)->default_value(0.0)->notifier(in_range("sky", -1e30, 1e30)),
         "sky level added, image units")
        ("noise-free", po::bool_switch(&o.noise_free), "no noise")
        ("saturation", po::value(&o.saturation)->value_name("LEVEL")
             ->notifier(in_range("saturation", 0.0, 1e300)),
         "full well, image units: pixels above it (sky and noise included) are set to it and "
         "the header's SATURATE says so, as a detector saturates (default: the --like "
         "image's SATURATE; 0: none)");
    options.group("Models").add_options()
        ("keep-negative", po::bool_switch(&s.keep_negative),
         "draw each galaxy's shapelet series exactly, negative pixels too (default: a galaxy's "
         "pixels below zero are set to zero, since light is never negative and a truncated "
         "series rings; the truth's flux is what was drawn)");
    options.group("Output").add_options()
        ("output,o", po::value<std::string>()->value_name("IMAGE"),
         "the FITS image to write (required); written as IMAGE.tmp.<pid> and renamed when "
         "complete")
        ("bunit", po::value(&s.bunit)->value_name("UNIT"),
         "the image's unit, written as BUNIT (e.g. electron/s, adu; default: a --like image's)")
        ("truth", po::value(&s.truth)->value_name("FILE"),
         "write what was drawn, for the objects centred in the image or --tile (JSON lines:\n"
         "position, true flux and shape, stamp)")
        ("bitpix", po::value(&s.bitpix)->default_value(-32), "-32 or -64");
    options.positional("input", 1);
    if (!options.parse(argc, argv)) return 0;
    const app::Log log("shapesim-render", options.common().verbosity);
    s.check(options);

    // The field and its window; the noise and the rest of the scene's options; the kernels.
    const FieldGeometry field = s.field.field(options);
    const Tile window =
        s.field.window(options, field, true).value_or(Tile{1, 1, field.nx, field.ny});
    s.finish_scene(options, field, log);
    SceneKernels kernels;
    if (!s.psf_analytic.empty()) {
        const AnalyticPsf profile = parse_analytic_psf(s.psf_analytic);
        const AnalyticPsfModel m = analytic_psf_model(profile, field.pixel_scale);
        log.info("PSF ", profile.describe(), ": n_max ", m.psf.n_max, ", FWHM ", m.fwhm,
                 "\" (model ", 100 * m.fwhm_error,
                 "%), encircled energy within 1 and 2 FWHM off by ",
                 100 * m.ee_error_1, "% and ", 100 * m.ee_error_2, "%");
        if (m.worst_error() > 0.01)
            log.warn("the analytic PSF's model misses 1% (worst error ", m.worst_error(),
                     "); shapesim-decompose --psf-analytic reports it in full");
        kernels = s.galaxy_psf.empty()
                      ? scene_kernels(m.psf.model)
                      : scene_kernels(m.psf.model,
                                      read_psf_model(s.galaxy_psf, field.pixel_scale),
                                      s.difference_order);
    } else if (!s.psf_field.empty()) {
        PsfField psf = read_psf_field(s.psf_field);
        log.info("PSF varying across the field (", s.psf_field, "): ",
                 psf.variation.degree == 0
                     ? std::string("constant (psfex's degree 0)")
                     : "degree " + std::to_string(psf.variation.degree) + " in x, y",
                 ", shapelets to n_max ", psf.n_max, ", beta ", psf.beta_pix,
                 " pixels, worst residual ", 100 * psf.max_residual_fraction, "% of the peak");
        if (!psf.reached_target)
            log.warn("the PSF field's shapelet model misses PSFEx's by ",
                     100 * psf.max_residual_fraction, "% of the peak somewhere across its stars");
        kernels = field_kernels(std::move(psf));
    } else {
        kernels = read_scene_kernels(s.psf, s.galaxy_psf, field.pixel_scale, s.difference_order);
    }

    // Read, prepare, paint, add noise; the image and the truth of the objects centred in it.
    using clock = std::chrono::steady_clock;
    const auto t_read = clock::now();
    ObjectPlacement placement;
    placement.have_psf = kernels.has_psf();
    placement.galaxy_psf_known = !s.galaxy_psf.empty();
    placement.by_sky = s.place_by_sky;
    std::vector<ObjectRecord> records =
        read_objects(s.input, field.wcs, s.band, placement, o.threads);
    const auto t_prepare = clock::now();
    if (kernels.field) {
        // psfex's polynomial holds between its stars; beyond them it is extrapolated.
        long outside = 0;
        for (const ObjectRecord& r : records)
            if (!kernels.field->variation.within_stars(*r.x, *r.y)) ++outside;
        if (outside > 0) {
            const PsfVariation& f = kernels.field->variation;
            log.warn(outside, " of ", records.size(), " objects lie beyond the stars the PSF field "
                     "was fitted to (x ", f.x_zero - 0.5 * f.x_scale, " to ",
                     f.x_zero + 0.5 * f.x_scale,
                     ", y ", f.y_zero - 0.5 * f.y_scale, " to ", f.y_zero + 0.5 * f.y_scale,
                     "): their PSF is the polynomial extrapolated; render the image psfex measured "
                     "(--like it)");
        }
    }
    // Lensing acts on light before the PSF: a model that already holds its image's PSF
    // (observed frame) is lensed PSF and all, which a shear calibration must not use.
    long observed_lensed = 0;
    for (const ObjectRecord& r : records)
        if (r.kind == "galaxy" && (r.lensing || o.lensing) &&
            !(r.extra.contains("frame") && r.extra.at("frame") == "intrinsic"))
            ++observed_lensed;
    if (observed_lensed > 0)
        log.info("note: ", observed_lensed, " lensed galaxies are observed-frame models: their "
                 "PSF is lensed with them (for a shear calibration draw intrinsic models, "
                 "shapesim-decompose --psf)");
    RenderedScene scene =
        prepare_field(records, field, kernels, o, window, s.input, ReleaseShapes{});
    s.draw_and_write(options, scene, records, kernels);
    if (const std::string note = app::clipped_note(summarise_clipped(scene), o.noise_rms);
        !note.empty())
        log.info(note);
    log.info(app::render_summary(scene, records.size(), window, kernels,
                            std::chrono::duration<double>(t_prepare - t_read).count()),
             "; peak memory ", app::Log::peak_memory_mib(), " MiB");
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "shapesim-render", run); }
