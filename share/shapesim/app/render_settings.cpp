#include "shapesim/app/render_settings.hpp"

#include "shapesim/app/provenance.hpp"
#include "shapesim/atomic_file.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/sources.hpp"

#include <cmath>
#include <optional>

namespace shapesim::app {

void RenderSettings::check(const ProgramOptions& options) {
    const std::string& output = options.common().output;
    if (output.empty()) throw po::error("give the output image: -o FILE");
    if (bitpix != -32 && bitpix != -64) throw po::error("--bitpix: -32 or -64");
    check_writable(output);
    if (!truth.empty()) check_writable(truth);
    if (!galaxy_psf.empty() && psf.empty()) throw po::error("--galaxy-psf needs --psf");
    const bool rms_given = options.given("noise-rms") || options.given("noise-correlation");
    if (options.given("noise-like") && rms_given)
        throw po::error("--noise-like sets --noise-rms and --noise-correlation");
    if (options.given("noise-model") && (options.given("noise-like") || rms_given))
        throw po::error("--noise-model sets the noise: not with --noise-like, --noise-rms, "
                        "--noise-correlation");
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
    if (o.noise_kernel)
        log.verbose("noise kernel radius ", o.noise_kernel->radius, ", ",
                    o.noise_kernel->columns.size(), " separable terms");
    if (!noise_weight.empty()) o.noise_scale = read_noise_scale(noise_weight, field.nx, field.ny);
    o.gain *= exposure;
    o.seed = band.empty() ? options.common().seed : band_seed(options.common().seed, band);
    o.threads = options.common().threads;
    o.clip_negative = !keep_negative;
    o.validate();
}

SceneLabels RenderSettings::labels(const ProgramOptions& options) const {
    return SceneLabels{options.common().seed, psf.empty() ? "none" : psf,
                       noise_label(noise_model, !noise_weight.empty()), band};
}

void RenderSettings::write_outputs(const ProgramOptions& options, const RenderedScene& rendered,
                                   const std::vector<ObjectRecord>& records,
                                   const SceneKernels& kernels) const {
    FitsWriter fits(options.common().output, "shapesim-render",
                    provenance_keywords(options, {"output", "truth"}));
    fits.write_image(rendered.image,
                     scene_image_spec(rendered, records, scene, kernels, labels(options), bitpix));
    std::optional<AtomicTextFile> file;
    if (!truth.empty())
        write_truth_records(file.emplace(truth).stream(), truth, rendered, records);
    fits.commit();
    if (file) file->commit();
}

}  // namespace shapesim::app
