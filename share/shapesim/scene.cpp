#include "shapesim/scene.hpp"

#include "shapesim/basis1d.hpp"
#include "shapesim/constants.hpp"
#include "shapesim/convolve.hpp"
#include "shapesim/error.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/parallel.hpp"
#include "shapesim/pixel_noise.hpp"
#include "shapesim/polar.hpp"
#include "shapesim/psf.hpp"
#include "shapesim/rng.hpp"

#include <algorithm>
#include <map>
#include <mutex>
#include <chrono>
#include <cmath>
#include <optional>
#include <sstream>
#include <thread>

namespace shapesim {

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

// Cramér's bound |φ_n(u)| ≤ 1.086435 π^{−1/4}, rounded up.
const double hermite_bound = 1.0865 * std::pow(pi, -0.25);

}  // namespace

void SceneOptions::validate() const {
    auto check = [](bool ok, const char* field, const char* why) {
        if (!ok) throw Error(why, "", 0, field);
    };
    check(truncation > 0.0 && truncation < 1.0, "truncation", "must be in (0, 1)");
    check(noise_rms >= 0.0 && std::isfinite(noise_rms), "noise_rms", "must be ≥ 0");
    check(noise_correlation >= 1.0 && std::isfinite(noise_correlation), "noise_correlation",
          "must be ≥ 1");
    check(gain >= 0.0 && std::isfinite(gain), "gain", "must be ≥ 0");
    check(std::isfinite(sky), "sky", "must be finite");
    check(lensing_tolerance >= 1e-14 && lensing_tolerance < 1.0, "lensing_tolerance",
          "must be in [1e-14, 1)");
    check(threads >= 1, "threads", "must be ≥ 1");
    check(photon_tolerance >= 0.0 && photon_tolerance < 1.0, "photon_tolerance",
          "must be in [0, 1)");
    check(saturation >= 0.0 && std::isfinite(saturation), "saturation", "must be ≥ 0");
}

double stamp_radius(const CartesianModel& model, double threshold) {
    const int n = model.n_max + 1;
    const double beta = model.beta_pix;
    std::vector<double> rows(std::size_t(n), 0.0), columns(std::size_t(n), 0.0);
    for (int n1 = 0; n1 < n; ++n1)
        for (int n2 = 0; n2 < n; ++n2) {
            rows[std::size_t(n1)] += std::abs(model.b(n1, n2));
            columns[std::size_t(n2)] += std::abs(model.b(n1, n2));
        }
    std::vector<double> phi(static_cast<std::size_t>(n)), turning(static_cast<std::size_t>(n));
    for (int k = 0; k < n; ++k) turning[std::size_t(k)] = std::sqrt(2.0 * k + 1.0);
    // Bound on a pixel wholly beyond R in x (or y): (C/β) Σ_n S_n T_n(R), T_n = |φ_n(R/β)| past
    // φ_n's last turning point √(2n+1) (it only falls from there), else C.
    auto bound = [&](double r) {
        const double u = r / beta;
        hermite_functions(u, model.n_max, phi.data());
        double sx = 0.0, sy = 0.0;
        for (int k = 0; k < n; ++k) {
            const double t = u >= turning[std::size_t(k)] ? std::abs(phi[std::size_t(k)])
                                                          : hermite_bound;
            sx += rows[std::size_t(k)] * t;
            sy += columns[std::size_t(k)] * t;
        }
        return hermite_bound / beta * std::max(sx, sy);
    };
    if (bound(0.0) <= threshold) return 0.0;
    double lo = 0.0, hi = beta * std::sqrt(2.0 * model.n_max + 1.0);
    while (bound(hi) > threshold) {
        lo = hi;
        hi += beta;
        if (hi > 1e6) return hi;  // never in practice: the tail is Gaussian
    }
    while (hi - lo > 0.01) {
        const double mid = 0.5 * (lo + hi);
        (bound(mid) > threshold ? lo : hi) = mid;
    }
    return hi;
}

double truncation_threshold(const CartesianModel& model, const SceneOptions& options) {
    if (!options.noise_free && options.noise_rms > 0.0)
        return options.truncation * options.noise_rms;
    std::vector<double> phi(std::size_t(model.n_max) + 1);
    hermite_functions(0.0, model.n_max, phi.data());
    double centre = 0.0;
    for (int n1 = 0; n1 <= model.n_max; ++n1)
        for (int n2 = 0; n2 <= model.n_max; ++n2)
            centre += model.b(n1, n2) * phi[std::size_t(n1)] * phi[std::size_t(n2)];
    centre = std::abs(centre) / model.beta_pix;
    if (!(centre > 0.0)) {  // a model with a hole at its centre: its mean surface brightness
        centre = std::abs(moments(model).flux) / (4.0 * pi * model.beta_pix * model.beta_pix);
    }
    return options.truncation * centre;
}

SceneKernels scene_kernels(const ShapeletModel& psf, const std::optional<ShapeletModel>& models_psf,
                           int difference_order) {
    SceneKernels kernels;
    kernels.star = to_cartesian(psf);
    if (!models_psf) {
        kernels.galaxy = kernels.star;
        kernels.galaxy_note = "the PSF";
    } else if (models_psf->n_max == psf.n_max && models_psf->beta_pix == psf.beta_pix &&
               models_psf->coeffs == psf.coeffs) {
        kernels.galaxy_note = "none (the models hold this PSF)";
    } else {
        const int order = difference_order >= 0 ? difference_order : psf.n_max;
        const DifferenceKernel k = difference_kernel(*models_psf, psf, order);
        kernels.galaxy = to_cartesian(k.kernel);
        kernels.galaxy_note = "difference kernel (relative residual " +
                              std::to_string(k.report.relative_residual) + ")";
    }
    return kernels;
}

SceneKernels field_kernels(PsfField field) {
    SceneKernels kernels;
    kernels.field = std::make_shared<const PsfField>(std::move(field));
    kernels.galaxy_note = "the PSF at each object's place (n_max " +
                          std::to_string(kernels.field->n_max) + ")";
    return kernels;
}

SceneKernels read_scene_kernels(const std::string& psf_path, const std::string& models_psf_path,
                                double pixel_scale, int difference_order) {
    if (psf_path.empty()) return SceneKernels{};
    const ShapeletModel psf = read_psf_model(psf_path, pixel_scale);
    if (models_psf_path.empty()) return scene_kernels(psf);
    return scene_kernels(psf, read_psf_model(models_psf_path, pixel_scale), difference_order);
}

void use_sky_noise(SceneOptions& options, const NoiseRecord& noise) {
    options.noise_rms = noise.rms;
    options.noise_correlation = std::max(1.0, noise.noise_correlation);
    options.noise_kernel = correlated_noise_kernel(noise.correlation);
    options.noise_marginal = noise.marginal;
}

ImageArray read_noise_scale(const std::string& path, long field_nx, long field_ny) {
    const ImageArray weight = read_fits_image(path);
    if (weight.cols() != field_nx || weight.rows() != field_ny)
        throw Error("the weight map is " + std::to_string(weight.cols()) + " x " +
                        std::to_string(weight.rows()) + " pixels, the field " +
                        std::to_string(field_nx) + " x " + std::to_string(field_ny),
                    path);
    try {
        return noise_scale_from_weight(weight);
    } catch (const Error& e) {
        throw Error(e.what(), path);
    }
}

std::vector<ObjectRecord> read_objects(const std::string& path, const Wcs& wcs,
                                       const std::string& band, const ObjectPlacement& placement,
                                       int threads) {
    JsonlReader reader(path, {ObjectRecord::schema});
    std::vector<long> lines;
    // Only what a render reads is kept of each record, as it is read.
    const auto keep_what_render_reads = [](ObjectRecord& r) {
        Json kept = Json::object();
        for (const char* key : render_record_keys)
            if (const auto it = r.extra.find(key); it != r.extra.end()) kept[key] = *it;
        r.extra = std::move(kept);
        r.flags = {};
        r.parent.reset();
    };
    std::vector<ObjectRecord> records =
        reader.read_all<ObjectRecord>(threads, &lines, keep_what_render_reads);
    for (std::size_t k = 0; k < records.size(); ++k) {
        ObjectRecord& r = records[k];
        if (!band.empty()) {
            try {
                r = r.in_band(band);
            } catch (const Error& e) {
                throw Error(e.message(), reader.name(), lines[k], e.field());
            }
        }
        const PixelPosition p = wcs.sky_to_pixel(r.ra, r.dec);
        if (!placement.by_sky && r.x && r.y &&
            !(std::hypot(p.x - *r.x, p.y - *r.y) <= placement.max_shift)) {
            std::ostringstream why;
            why << "object " << r.id << " was drawn for another field: its x, y (" << *r.x
                << ", " << *r.y << ") are (" << p.x << ", " << p.y
                << ") here; give render the field shapesim-sample had (--like, or --area/--size "
                   "with --pixel-scale, --ra, --dec), or --place-by-sky";
            throw Error(why.str(), reader.name(), lines[k], "x");
        }
        r.x = p.x;
        r.y = p.y;
        if (!r.has_shape() && !placement.have_psf)
            throw Error("object " + r.id + " is a point source: give --psf", reader.name(),
                        lines[k], "kind");
        if (r.has_shape() && placement.have_psf && !placement.galaxy_psf_known &&
            r.extra.contains("frame") && r.extra.at("frame") == "observed")
            throw Error("object " + r.id + " is an observed-frame model: it already holds its "
                        "field's PSF; give --galaxy-psf that PSF (it is then convolved with the "
                        "difference only), or draw from an intrinsic model",
                        reader.name(), lines[k], "frame");
        r.bands = {};  // in_band chose its own
    }
    return records;
}

PreparedObject prepare_object(const ObjectRecord& record, double field_pixel_scale,
                              const SceneKernels& kernels, const SceneOptions& options,
                              ConvolveWorkspace* workspace) {
    if (!record.x || !record.y)
        throw Error("no x, y: give positions in the field (shapesim-sample --like)", "", 0, "x");
    PreparedObject p;
    p.id = record.id;
    p.kind = record.kind;
    CartesianModel model;
    if (record.has_shape()) {
        ShapeletModel m = record.to_model(*record.x, *record.y);
        if (record.pixel_scale != field_pixel_scale)
            m = dilate(m, record.pixel_scale / field_pixel_scale);
        // An intrinsic model (fitted through its image's PSF) is observed through the PSF
        // itself; an observed-frame one through the galaxy kernel.
        const bool intrinsic =
            record.extra.contains("frame") && record.extra.at("frame") == "intrinsic";
        if (intrinsic && !kernels.has_psf())
            throw Error("object " + record.id + " is an intrinsic model: give --psf", "", 0,
                        "frame");
        std::optional<CartesianModel> here;  // the PSF where it is, when the PSF varies
        if (kernels.field) {
            here = kernels.field->at(*record.x, *record.y);
            p.psf = ShapeSummary::of(moments(*here));
        }
        const std::optional<CartesianModel>& star = kernels.field ? here : kernels.star;
        const std::optional<CartesianModel>& kernel = kernels.field ? here
                                                      : intrinsic   ? kernels.star
                                                                    : kernels.galaxy;
        // Never sharper than it was seen: an intrinsic model fitted through a PSF broader than
        // the target's carries no real structure below that PSF's scale (only the fit's
        // ringing), so it is first smoothed by the Gaussian that brings the target's scale to
        // its own (Gaussian scales add in quadrature; an n_max 0 kernel keeps the order).
        std::optional<CartesianModel> smoothing;
        if (intrinsic && star && record.extra.contains("psf_beta") &&
            record.extra.at("psf_beta").is_number()) {
            const double seen = record.extra.at("psf_beta").get<double>() / field_pixel_scale;
            const double target = star->beta_pix;
            if (seen > target) {
                CartesianModel gaussian(0.0, 0.0, std::sqrt(seen * seen - target * target), 0);
                gaussian.b(0, 0) = 1.0;
                gaussian.b(0, 0) = 1.0 / flux(to_polar(gaussian));  // unit flux
                smoothing = gaussian;
            }
        }
        auto smooth = [&](const CartesianModel& c) {
            ConvolveWorkspace local;
            return convolve(c, *smoothing, workspace ? *workspace : local);
        };
        // The galaxy's own lensing (shapesim-lens), or the scene's one shear for all.
        if (record.lensing && options.lensing)
            throw Error("carries its own lensing (shapesim-lens): --shear/--kappa would lens it "
                        "twice",
                        "", 0, "lensing");
        const std::optional<Lensing>& lensing = record.lensing ? record.lensing : options.lensing;
        // The smoothing is the galaxy's (the finest it was seen at): lensed with it. (Without
        // lensing it is applied after, the same to rounding and one conversion fewer.)
        if (smoothing && lensing) {
            m = to_polar(smooth(to_cartesian(m)));
            smoothing.reset();
        }
        if (lensing) {
            p.unlensed_epsilon = moments(m).epsilon;
            p.lensing = *lensing;
            ProjectionOptions po;
            po.tolerance = options.lensing_tolerance;
            const Projection lensed = lens(m, *lensing, po);
            m = lensed.model;
            p.lensing_error = lensed.relative_error;
        }
        const Moments seen = moments(m);
        p.intrinsic = ShapeSummary::of(seen);
        p.flux = seen.flux;
        model = to_cartesian(m);
        if (smoothing) model = smooth(model);
        if (kernel) {
            ConvolveWorkspace local;
            model = convolve(model, *kernel, workspace ? *workspace : local);
        }
    } else {
        if (!kernels.has_psf())
            throw Error("a point source needs a PSF (--psf)", "", 0, "coeffs");
        if (kernels.field) {
            model = kernels.field->at(*record.x, *record.y);
            p.psf = ShapeSummary::of(moments(model));
        } else {
            model = *kernels.star;
        }
        model.b *= record.flux;
        model.x = *record.x;
        model.y = *record.y;
        p.flux = record.flux;
    }
    p.radius = stamp_radius(model, truncation_threshold(model, options));
    p.drawn = p.radius > 0.0;
    // Columns whose pixel [i − ½, i + ½] meets (x − R, x + R): i from ⌊x − R − ½⌋ + 1 to
    // ⌈x + R + ½⌉ − 1 (FITS), 0-based from there.
    const double i0 = std::floor(model.x - p.radius - 0.5) + 1.0;
    const double i1 = std::ceil(model.x + p.radius + 0.5) - 1.0;
    const double j0 = std::floor(model.y - p.radius - 0.5) + 1.0;
    const double j1 = std::ceil(model.y + p.radius + 0.5) - 1.0;
    // A runaway β (10⁶″) reaches beyond any image: kept within ±2³⁰ pixels here, so the int
    // window holds it, and within the field by prepare_field.
    constexpr double reach = double(1L << 30);
    auto bounded = [&](double v) { return long(std::clamp(v, -reach, reach)); };
    const long c_lo = bounded(i0 - 1.0), c_hi = bounded(i1);
    const long r_lo = bounded(j0 - 1.0), r_hi = bounded(j1);
    p.window = PixelWindow{int(c_lo), int(r_lo), int(c_hi - c_lo), int(r_hi - r_lo)};
    p.model = std::move(model);
    return p;
}

bool stamp_reaches(const PixelWindow& stamp, const Tile& window) {
    // Columns column0 … column0 + nx − 1 (0-based) against x0 − 1 … x1 − 1; rows alike.
    return stamp.column0 + stamp.nx > window.x0 - 1 && stamp.column0 < window.x1 &&
           stamp.row0 + stamp.ny > window.y0 - 1 && stamp.row0 < window.y1;
}

namespace {

// prepare_scene; with `release`, each record keeps only what the truth reads once prepared.
std::vector<PreparedObject> prepare_records(const std::vector<ObjectRecord>& records,
                                            std::vector<ObjectRecord>* release,
                                            double field_pixel_scale, const SceneKernels& kernels,
                                            const SceneOptions& options, const Tile& window) {
    std::vector<PreparedObject> prepared(records.size());
    // Errors are rare: kept by record, the first in record order reported.
    std::map<std::size_t, std::string> errors;
    std::mutex errors_lock;
    std::vector<ConvolveWorkspace> workspaces(std::size_t(std::max(1, options.threads)));
    parallel_for(records.size(), options.threads, [&](std::size_t k, int t) {
        try {
            prepared[k] = prepare_object(records[k], field_pixel_scale, kernels, options,
                                         &workspaces[std::size_t(t)]);
            prepared[k].index = k;
            if (release) keep_for_truth((*release)[k]);
        } catch (const std::exception& e) {
            const std::lock_guard<std::mutex> hold(errors_lock);
            errors.emplace(k, e.what());
        }
    });
    if (!errors.empty()) {
        const auto& [k, why] = *errors.begin();
        throw Error("object " + records[k].id + ": " + why);
    }
    // Those that reach the window, in place (a second vector would double the peak).
    prepared.erase(std::remove_if(prepared.begin(), prepared.end(),
                                  [&](const PreparedObject& p) {
                                      return !(p.drawn && stamp_reaches(p.window, window));
                                  }),
                   prepared.end());
    return prepared;
}

}  // namespace

void keep_for_truth(ObjectRecord& record) {
    std::vector<Complex>().swap(record.coeffs);
    std::vector<BandCoefficients>().swap(record.bands);
    const auto ring = record.extra.find("ring");
    record.extra = ring != record.extra.end() ? Json{{"ring", *ring}} : Json();
}

std::vector<PreparedObject> prepare_scene(const std::vector<ObjectRecord>& records,
                                          double field_pixel_scale, const SceneKernels& kernels,
                                          const SceneOptions& options, const Tile& window) {
    return prepare_records(records, nullptr, field_pixel_scale, kernels, options, window);
}

std::vector<PreparedObject> prepare_scene(std::vector<ObjectRecord>& records,
                                          double field_pixel_scale, const SceneKernels& kernels,
                                          const SceneOptions& options, const Tile& window,
                                          ReleaseShapes) {
    return prepare_records(records, &records, field_pixel_scale, kernels, options, window);
}

namespace {

// prepare_field; with `release` (the records themselves), prepare_scene(…, ReleaseShapes).
RenderedScene prepare_window(const std::vector<ObjectRecord>& records,
                             std::vector<ObjectRecord>* release, const FieldGeometry& field,
                             const SceneKernels& kernels, const SceneOptions& options,
                             const Tile& window, const std::string& source) {
    const auto start = Clock::now();
    RenderedScene scene;
    scene.field = field;
    scene.window = window;
    try {
        scene.objects =
            prepare_records(records, release, field.pixel_scale, kernels, options, window);
    } catch (const Error& e) {
        throw e.at(source);
    }
    // A stamp wider or taller than the field is cut to the field (the same cut in every tile,
    // so tiles still add up to the whole): a runaway β costs the field's pixels at most, not
    // its own nominal extent (issue 39). Stamps within the field's size are left whole.
    for (PreparedObject& p : scene.objects)
        if (p.window.nx > field.nx || p.window.ny > field.ny)
            p.window = p.window.clipped_to(field.nx, field.ny);
    scene.clipped.assign(scene.objects.size(), ClippedLight{});
    scene.prepare_seconds = seconds_since(start);
    return scene;
}

}  // namespace

RenderedScene prepare_field(const std::vector<ObjectRecord>& records, const FieldGeometry& field,
                            const SceneKernels& kernels, const SceneOptions& options,
                            const Tile& window, const std::string& source) {
    return prepare_window(records, nullptr, field, kernels, options, window, source);
}

RenderedScene prepare_field(std::vector<ObjectRecord>& records, const FieldGeometry& field,
                            const SceneKernels& kernels, const SceneOptions& options,
                            const Tile& window, const std::string& source, ReleaseShapes) {
    return prepare_window(records, &records, field, kernels, options, window, source);
}

std::uint64_t band_seed(std::uint64_t seed, const std::string& band) {
    // A SplitMix64 finaliser over seed ⊕ hash: nearby seeds and similar names land far apart.
    std::uint64_t z = seed ^ fnv1a_64(band);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

}  // namespace shapesim
