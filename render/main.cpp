// shapesim-render: shapesim.object/1 records → a FITS image with a WCS (paper §4.3;
// DESIGN §3, §6). The work is in the library: scene.hpp (lensing, convolution, stamps,
// painting, noise), convolve.hpp, transform.hpp, render.hpp.
#include "shapesim/app/atomic_file.hpp"
#include "shapesim/app/field_options.hpp"
#include "shapesim/app/options.hpp"
#include "shapesim/app/provenance.hpp"
#include "shapesim/app/run_main.hpp"
#include "shapesim/convolve.hpp"
#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/geometry.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/polar.hpp"
#include "shapesim/psf.hpp"
#include "shapesim/records.hpp"
#include "shapesim/scene.hpp"
#include "shapesim/statistics.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>

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
    "  shapesim-render --psf psf.jsonl --size 1 --noise-free -o clean.fits < objects.jsonl";

struct Settings {
    std::string input = "-", psf, galaxy_psf, truth, noise_like, noise_model, noise_weight, band;
    app::FieldOptions field;
    std::vector<double> shear;
    double kappa = 0.0, exposure = 1.0;
    int bitpix = -32, difference_order = -1;
    bool keep_negative = false;
    SceneOptions scene;
};

// The field's noise from shapesim-detect's records: its background_rms (the median of the
// stamps' noise_rms in records without one), and the median noise_correlation.
std::pair<double, double> noise_of(const std::string& path) {
    JsonlReader reader(path, {SourceRecord::schema});
    SourceRecord r;
    std::vector<double> rms, field_rms, factor;
    while (reader.next_record(r)) {
        try {
            if (auto v = optional_double(r.extra, "background_rms"); v && *v > 0.0) field_rms.push_back(*v);
            if (auto v = optional_double(r.extra, "noise_rms")) rms.push_back(*v);
            if (auto v = optional_double(r.extra, "noise_correlation")) factor.push_back(*v);
        } catch (const Error& e) {
            throw reader.locate(e);
        }
    }
    if (rms.empty() && field_rms.empty()) throw Error("no background_rms or noise_rms in the records", path);
    return {median_of_values(field_rms.empty() ? rms : field_rms),
            factor.empty() ? 1.0 : std::max(1.0, median_of_values(factor))};
}

int run(int argc, const char* const argv[]) {
    app::ProgramOptions options("shapesim-render", "[OPTION]... -o IMAGE", description,
                                app::Common::output | app::Common::quiet | app::Common::verbose |
                                    app::Common::threads | app::Common::seed | app::Common::like |
                                    app::Common::config | app::Common::print_params);
    Settings s;
    SceneOptions& o = s.scene;
    using app::in_range;
    options.group("Input").add_options()
        ("input,i", po::value(&s.input)->value_name("FILE")->default_value("-"),
         "object records (default: stdin)")
        ("band", po::value(&s.band)->value_name("NAME"),
         "draw every object as it is in this band of its \"bands\" (multi-band records); the "
         "noise is this band's own realisation of --seed")
        ("psf", po::value(&s.psf)->value_name("FILE"),
         "PSF shapelet record of the image (shapesim-decompose --psf-image): stars are drawn "
         "as it, galaxies convolved with it")
        ("galaxy-psf", po::value(&s.galaxy_psf)->value_name("FILE"),
         "the PSF the galaxy models already hold (e.g. models of real galaxies): galaxies are "
         "convolved with the difference kernel psf / galaxy-psf, or not at all when equal")
        ("difference-order", po::value(&s.difference_order)->value_name("N"),
         "order of the difference kernel (default: the PSF's)");
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
         "autocorrelation, drawn as white noise through the kernel that has it")
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
         "seconds, for images in units per second")
        ("sky", po::value(&o.sky)->default_value(0.0)->notifier(in_range("sky", -1e30, 1e30)),
         "sky level added, image units")
        ("noise-free", po::bool_switch(&o.noise_free), "no noise");
    options.group("Models").add_options()
        ("keep-negative", po::bool_switch(&s.keep_negative),
         "draw each galaxy's shapelet series exactly, negative pixels too (default: a galaxy's "
         "pixels below zero are set to zero, since light is never negative and a truncated "
         "series rings; the truth's flux is what was drawn)");
    options.group("Output").add_options()
        ("truth", po::value(&s.truth)->value_name("FILE"),
         "write what was drawn, for the objects centred in the image or --tile (JSON lines:\n"
         "position, true flux and shape, stamp)")
        ("bitpix", po::value(&s.bitpix)->default_value(-32), "-32 or -64");
    if (!options.parse(argc, argv)) return 0;
    const app::Log log("shapesim-render", options.common().verbosity);
    using clock = std::chrono::steady_clock;

    const std::string& output = options.common().output;
    if (output.empty()) throw po::error("give the output image: -o FILE");
    if (s.bitpix != -32 && s.bitpix != -64) throw po::error("--bitpix: -32 or -64");
    app::check_writable(output);
    if (!s.truth.empty()) app::check_writable(s.truth);
    if (!s.galaxy_psf.empty() && s.psf.empty()) throw po::error("--galaxy-psf needs --psf");
    if (options.given("noise-like") && (options.given("noise-rms") || options.given("noise-correlation")))
        throw po::error("--noise-like sets --noise-rms and --noise-correlation");
    if (options.given("noise-model") &&
        (options.given("noise-like") || options.given("noise-rms") || options.given("noise-correlation")))
        throw po::error("--noise-model sets the noise: not with --noise-like, --noise-rms, "
                        "--noise-correlation");
    if (!s.shear.empty()) {
        if (s.shear.size() != 2) throw po::error("--shear takes two numbers: G1 G2");
        if (!(std::hypot(s.shear[0], s.shear[1]) < 1.0)) throw po::error("--shear: |g| must be < 1");
    }
    if (!s.shear.empty() || s.kappa != 0.0) {
        Lensing l;
        if (!s.shear.empty()) {
            l.g1 = s.shear[0];
            l.g2 = s.shear[1];
        }
        l.kappa = s.kappa;
        o.lensing = l;
    }

    // The field and the window.
    const FieldGeometry field = s.field.field(options);
    const Tile window = s.field.window(options, field, true).value_or(Tile{1, 1, field.nx, field.ny});

    // Noise and kernels.
    if (!s.noise_like.empty()) std::tie(o.noise_rms, o.noise_correlation) = noise_of(s.noise_like);
    std::string noise_note = "drizzle-like 3x3 (NOISECOR)";
    if (!s.noise_model.empty()) {
        const NoiseRecord noise = read_noise_record(s.noise_model);
        o.noise_rms = noise.rms;
        o.noise_correlation = std::max(1.0, noise.noise_correlation);
        o.noise_kernel = correlated_noise_kernel(noise.correlation);
        noise_note = s.noise_model;
        log.verbose("noise kernel radius ", o.noise_kernel->radius, ", ",
                    o.noise_kernel->columns.size(), " separable terms");
    }
    if (!s.noise_weight.empty()) {
        const ImageArray weight = read_fits_image(s.noise_weight);
        if (weight.cols() != field.nx || weight.rows() != field.ny)
            throw Error("the weight map is " + std::to_string(weight.cols()) + " x " +
                            std::to_string(weight.rows()) + " pixels, the field " +
                            std::to_string(field.nx) + " x " + std::to_string(field.ny),
                        s.noise_weight);
        try {
            o.noise_scale = noise_scale_from_weight(weight);
        } catch (const Error& e) {
            throw Error(e.what(), s.noise_weight);
        }
        noise_note += ", scaled by the weight map";
    }
    o.gain *= s.exposure;
    o.seed = s.band.empty() ? options.common().seed : band_seed(options.common().seed, s.band);
    o.threads = options.common().threads;
    o.validate();
    SceneKernels kernels;
    std::string kernel_note = "none";
    if (!s.psf.empty()) {
        const ShapeletModel psf = read_psf_model(s.psf, field.pixel_scale);
        kernels.star = to_cartesian(psf);
        if (s.galaxy_psf.empty()) {
            kernels.galaxy = kernels.star;
            kernel_note = "the PSF";
        } else {
            const ShapeletModel old = read_psf_model(s.galaxy_psf, field.pixel_scale);
            if (old.n_max == psf.n_max && old.beta_pix == psf.beta_pix && old.coeffs == psf.coeffs) {
                kernel_note = "none (the models hold this PSF)";
            } else {
                const int order = s.difference_order >= 0 ? s.difference_order : psf.n_max;
                const DifferenceKernel k = difference_kernel(old, psf, order);
                kernels.galaxy = to_cartesian(k.kernel);
                kernel_note = "difference kernel (relative residual " +
                              std::to_string(k.report.relative_residual) + ")";
            }
        }
    }

    // Read the objects; positions from ra/dec through the field's WCS.
    const auto t_read = clock::now();
    JsonlReader reader(s.input, {ObjectRecord::schema});
    std::vector<long> lines;
    std::vector<ObjectRecord> records = reader.read_all<ObjectRecord>(o.threads, &lines);
    for (std::size_t k = 0; k < records.size(); ++k) {
        ObjectRecord& r = records[k];
        if (!s.band.empty()) {
            try {
                r = r.in_band(s.band);
            } catch (const Error& e) {
                throw Error(e.message(), reader.name(), lines[k], e.field());
            }
        }
        const PixelPosition p = field.wcs.sky_to_pixel(r.ra, r.dec);
        r.x = p.x;
        r.y = p.y;
        if (!r.has_shape() && !kernels.star)
            throw Error("object " + r.id + " is a point source: give --psf", reader.name(),
                        lines[k], "kind");
    }

    // Prepare (lens, convolve, size the stamps) in parallel; paint; noise.
    const auto t_prepare = clock::now();
    std::vector<PreparedObject> in_window;
    try {
        in_window = prepare_scene(records, field.pixel_scale, kernels, o, window);
    } catch (const Error& e) {
        throw e.at(reader.name());
    }
    const auto t_paint = clock::now();
    o.clip_negative = !s.keep_negative;
    std::vector<ClippedLight> clipped;
    ImageArray image = paint(in_window, window, o, &clipped);
    const auto t_noise = clock::now();
    add_noise(image, window, field.nx, o);
    const auto t_write = clock::now();

    // The image: the field's WCS moved to the window.
    FitsImageSpec spec;
    spec.extname = "SCI";
    spec.bitpix = s.bitpix;
    spec.bunit = field.bunit;  // a field made --like an image keeps its units
    Wcs wcs = field.wcs;
    wcs.crpix1 -= double(window.x0 - 1);
    wcs.crpix2 -= double(window.y0 - 1);
    spec.wcs = wcs;
    spec.keywords = {
        FitsKeyword("SEED", std::to_string(options.common().seed), "run seed (shapesim)"),
        FitsKeyword("NOBJ", (long long)(in_window.size()), "objects drawn in this image"),
        FitsKeyword("TRUNC", o.truncation, "stamp truncation, fraction of noise rms or peak"),
        FitsKeyword("NOISERMS", o.noise_free ? 0.0 : o.noise_rms, "Gaussian background rms"),
        FitsKeyword("NOISECOR", o.noise_correlation, "correlated-noise factor F (4x4 blocks)"),
        FitsKeyword("NOISEMOD", noise_note, "background noise correlation"),
        FitsKeyword("GAIN", o.noise_free ? 0.0 : o.gain, "electrons per image unit (photon noise)"),
        FitsKeyword("SKY", o.sky, "sky level added"),
        FitsKeyword("NOISEFRE", o.noise_free, "noise-free image"),
        FitsKeyword("G1", o.lensing ? o.lensing->g1 : 0.0, "reduced shear applied"),
        FitsKeyword("G2", o.lensing ? o.lensing->g2 : 0.0, "reduced shear applied"),
        FitsKeyword("KAPPA", o.lensing ? o.lensing->kappa : 0.0, "convergence applied"),
        FitsKeyword("LENSTOL", o.lensing_tolerance, "lensing projection tolerance"),
        FitsKeyword("PSF", s.psf.empty() ? std::string("none") : s.psf, "PSF record"),
        FitsKeyword("GALKERN", kernel_note, "what galaxies were convolved with"),
        FitsKeyword("TILEX0", (long long)window.x0, "first field column of this image"),
        FitsKeyword("TILEY0", (long long)window.y0, "first field row of this image"),
        FitsKeyword("FIELDNX", (long long)field.nx, "field width, pixels"),
        FitsKeyword("FIELDNY", (long long)field.ny, "field height, pixels"),
    };
    if (!s.band.empty()) spec.keywords.emplace_back("BAND", s.band, "band of the objects drawn");
    // The objects' own zero point (mag + 2.5 log₁₀ flux, when every object with both agrees):
    // a simulation measured without --zero-point gets its true magnitudes.
    std::optional<double> zero_point;
    bool agree = true;
    for (const ObjectRecord& r : records) {
        if (!r.mag || !(r.flux > 0.0)) continue;
        const double zp = *r.mag + 2.5 * std::log10(r.flux);
        if (!zero_point) zero_point = zp;
        else if (std::abs(zp - *zero_point) > 1e-6) agree = false;
    }
    if (zero_point && agree)
        spec.keywords.emplace_back("MAGZERO", std::round(*zero_point * 1e6) / 1e6,
                                   "AB zero point: mag = MAGZERO - 2.5 log10(value)");
    FitsWriter fits(output, "shapesim-render",
                    app::provenance_keywords(options, {"output", "truth"}));
    fits.write_image(image, spec);

    // The truth catalogue: the objects centred in the window, so the truths of a grid of tiles
    // hold every object once (stamps reaching in from outside are drawn, not listed).
    std::unique_ptr<app::AtomicTextFile> truth;
    if (!s.truth.empty()) {
        truth = std::make_unique<app::AtomicTextFile>(s.truth);
        JsonlWriter out(truth->stream(), s.truth);
        for (const PreparedObject& p : in_window) {
            if (!window.owns(p.model.x, p.model.y)) continue;
            Json t = Json::object();
            t["schema"] = "shapesim.truth/1";
            t["id"] = p.id;
            t["kind"] = p.kind;
            const ObjectRecord& rec = records[p.index];
            t["ra"] = rec.ra;
            t["dec"] = rec.dec;
            t["x"] = p.model.x;
            t["y"] = p.model.y;
            // The light drawn: the model's, plus the negative light clipped away.
            const std::size_t i = std::size_t(&p - in_window.data());
            const double flux = p.flux + clipped[i].flux;
            t["flux"] = flux;
            if (rec.mag) t["mag"] = *rec.mag - 2.5 * std::log10(flux / rec.flux);
            if (clipped[i].flux > 0.0) t["clipped_flux"] = clipped[i].flux;
            if (p.intrinsic) {
                // Undefined (null) for a model whose second moments are not positive.
                const Complex e = p.intrinsic->epsilon;
                t["e1"] = std::isfinite(e.real()) ? Json(e.real()) : Json(nullptr);
                t["e2"] = std::isfinite(e.imag()) ? Json(e.imag()) : Json(nullptr);
                const double r = p.intrinsic->rms_radius;
                t["rms_radius"] = std::isfinite(r) ? Json(r) : Json(nullptr);
                t["lensing_error"] = p.lensing_error;
            }
            t["n_max"] = p.model.n_max;
            t["stamp_radius"] = p.radius;
            out.write(t);
        }
    }
    fits.commit();
    if (truth) truth->commit();
    const auto t_end = clock::now();
    long clipped_count = 0;
    double clipped_share = 0.0, deepest = 0.0;
    for (std::size_t i = 0; i < clipped.size(); ++i) {
        if (!(clipped[i].flux > 0.0)) continue;
        ++clipped_count;
        clipped_share = std::max(clipped_share, clipped[i].flux / std::abs(in_window[i].flux));
        deepest = std::min(deepest, clipped[i].deepest);
    }
    if (clipped_count > 0)
        log.info(clipped_count, " galaxies had negative model light, set to zero (at most ",
                 clipped_share, " of a galaxy's flux; deepest pixel ", deepest,
                 o.noise_rms > 0.0 ? " = " + std::to_string(deepest / o.noise_rms) + " sigma" : std::string(),
                 ")");
    auto seconds = [](auto a, auto b) { return std::chrono::duration<double>(b - a).count(); };
    log.info(in_window.size(), " of ", records.size(), " objects drawn into ", window.x1 - window.x0 + 1,
             " x ", window.y1 - window.y0 + 1, " pixels; galaxy kernel: ", kernel_note,
             "; read ", seconds(t_read, t_prepare), " s, prepare (lens, convolve) ",
             seconds(t_prepare, t_paint), " s, paint ", seconds(t_paint, t_noise), " s, noise ",
             seconds(t_noise, t_write), " s, write ", seconds(t_write, t_end), " s; peak memory ",
             app::Log::peak_memory_mib(), " MiB");
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "shapesim-render", run); }
