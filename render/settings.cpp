#include "render/settings.hpp"

#include "shapesim/analytic_psf.hpp"
#include "shapesim/error.hpp"

#include "app/provenance.hpp"
#include "shapesim/atomic_file.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/sources.hpp"

#include <chrono>
#include <cmath>
#include <optional>
#include <sstream>

namespace shapesim::app {

std::string clipped_note(const ClippedSummary& c, double noise_rms) {
    if (c.galaxies <= 0) return {};
    std::ostringstream note;
    note << c.galaxies << " galaxies had negative model light, set to zero (at most " << c.largest
         << " of a galaxy's flux; deepest pixel " << c.deepest
;
    if (noise_rms > 0.0) note << " = " << c.deepest / noise_rms << " sigma";
    note << ")";
    return note.str();
}

std::string render_summary(const RenderedScene& scene, std::size_t records, const Tile& window,
                           const SceneKernels& kernels, double read_seconds) {
    std::ostringstream line;
    line << scene.objects.size() << " of " << records << " objects drawn into "
         << window.x1 - window.x0 + 1 << " x " << window.y1 - window.y0 + 1
         << " pixels; galaxy kernel: " << kernels.galaxy_note << "; read " << read_seconds
         << " s, prepare (lens, convolve) " << scene.prepare_seconds << " s, paint "
         << scene.paint_seconds << " s, noise " << scene.noise_seconds << " s, write "
         << scene.sink_seconds << " s";
    return line.str();
}

std::string noise_label(const std::string& noise_model, bool weighted) {
    std::string label = noise_model.empty() ? "drizzle-like 3x3 (NOISECOR)" : noise_model;
    if (weighted) label += ", scaled by the weight map";
    return label;
}

void RenderSettings::check(const ProgramOptions& options) {
    const std::string& output = options.common().output;
    if (output.empty()) throw po::error("give the output image: -o FILE");
    if (bitpix != -32 && bitpix != -64) throw po::error("--bitpix: -32 or -64");
    check_writable(output);
    if (!truth.empty()) check_writable(truth);
    if (!psf_field.empty() && (!psf.empty() || !psf_analytic.empty()))
        throw po::error("--psf-field is the PSF: not with --psf or --psf-analytic");
    if (!psf_field.empty() && !galaxy_psf.empty())
        throw po::error("--psf-field with --galaxy-psf: a PSF varying across the field draws "
                        "intrinsic models (shapesim-decompose --psf), not observed-frame ones");
    if (!galaxy_psf.empty() && psf.empty() && psf_analytic.empty())
        throw po::error("--galaxy-psf needs --psf or --psf-analytic");
    if (!psf.empty() && !psf_analytic.empty())
        throw po::error("--psf and --psf-analytic exclude each other");
    if (!psf_analytic.empty()) {
        try {
            parse_analytic_psf(psf_analytic);
        } catch (const Error& e) {
            throw po::error("--psf-analytic: " + e.message());
        }
    }
    const bool rms_given = options.given("noise-rms") || options.given("noise-correlation");
    if (options.given("noise-like") && rms_given)
        throw po::error("--noise-like sets --noise-rms and --noise-correlation");
    if (options.given("noise-model") && (options.given("noise-like") || rms_given))
        throw po::error("--noise-model sets the noise: not with --noise-like, --noise-rms, "
                        "--noise-correlation");
    if (gaussian_noise && !options.given("noise-model"))
        throw po::error("--gaussian-noise needs --noise-model");
    if (!shear.empty() && shear.size() != 2) throw po::error("--shear takes two numbers: G1 G2");
    if (!shear.empty() && !(std::hypot(shear[0], shear[1]) < 1.0))
        throw po::error("--shear: |g| must be < 1");
    const double g1 = shear.empty() ? 0.0 : shear[0], g2 = shear.empty() ? 0.0 : shear[1];
    if (!shear.empty() || kappa != 0.0) scene.lensing = Lensing{g1, g2, kappa};
}

void RenderSettings::finish_scene(const ProgramOptions& options, const FieldGeometry& field,
                                  const Log& log) {
    SceneOptions& o = scene;
    if (!noise_like.empty()) {
        const FieldNoise noise = read_field_noise(noise_like);
        o.noise_rms = noise.rms;
        o.noise_correlation = noise.correlation;
    }
    if (!noise_model.empty()) use_sky_noise(o, read_noise_record(noise_model));
    if (gaussian_noise) o.noise_marginal = SkyMarginal{};
    if (!o.noise_marginal.empty())
        log.verbose("noise marginal: ", o.noise_marginal.values.size(), " levels, z from ",
                    o.noise_marginal.z0);
    if (o.noise_kernel)
        log.verbose("noise kernel radius ", o.noise_kernel->radius, ", ",
                    o.noise_kernel->columns.size(), " separable terms");
    if (!noise_weight.empty()) o.noise_scale = read_noise_scale(noise_weight, field.nx, field.ny);
    // A simulation --like a saturating image saturates where it does.
    if (!options.given("saturation")) o.saturation = field.saturate;
    o.gain *= exposure;
    o.seed = band.empty() ? options.common().seed : band_seed(options.common().seed, band);
    o.threads = options.common().threads;
    o.clip_negative = !keep_negative;
    o.validate();
}

SceneLabels RenderSettings::labels(const ProgramOptions& options) const {
    return SceneLabels{options.common().seed,
                       !psf_analytic.empty() ? psf_analytic
                       : !psf_field.empty()   ? psf_field
                       : psf.empty()          ? "none"
                                              : psf,
                       noise_label(noise_model, !noise_weight.empty()), band,
                       options.given("exptime")    ? exptime
                       : options.given("exposure") ? exposure
                                                   : 0.0,
                       bunit};
}

void RenderSettings::draw_and_write(const ProgramOptions& options, RenderedScene& rendered,
                                    const std::vector<ObjectRecord>& records,
                                    const SceneKernels& kernels) const {
    using clock = std::chrono::steady_clock;
    const FitsImageSpec spec =
        scene_image_spec(rendered, records, scene, kernels, labels(options), bitpix);
    auto start = [&](std::optional<FitsWriter>& fits) {
        fits.reset();  // the temporary of a writer given up is removed before the next one
        fits.emplace(options.common().output, "shapesim-render",
                     provenance_keywords(options, {"output", "truth"}));
    };
    std::optional<FitsWriter> fits;
    start(fits);
    const Tile& w = rendered.window;
    try {
        fits->begin_image(w.y1 - w.y0 + 1, w.x1 - w.x0 + 1, spec);
        draw_in_strips(rendered, scene, default_strip_rows(w.x1 - w.x0 + 1),
                       [&](long, const ImageArray& strip) { fits->write_rows(strip); });
    } catch (const FloatRangeError&) {
        // A pixel a float cannot hold (BITPIX −32): the whole window, promoted to −64.
        start(fits);
        draw_whole(rendered, scene);  // paint() sets every object's clipped light afresh
        const auto t0 = clock::now();
        fits->write_image(rendered.image, spec);
        rendered.sink_seconds = std::chrono::duration<double>(clock::now() - t0).count();
    }
    const auto t0 = clock::now();
    std::optional<AtomicTextFile> file;
    if (!truth.empty())
        write_truth_records(file.emplace(truth).stream(), truth, rendered, records);
    fits->commit();
    if (file) file->commit();
    rendered.sink_seconds += std::chrono::duration<double>(clock::now() - t0).count();
}

}  // namespace shapesim::app
