// Scene benchmarks (scene.hpp, shapesim-render's work): run time and the pixel error it buys.
//   BM_SceneTruncation/k   a 1024² field of 1000 objects (test::synthetic_morphology(heavy),
//                          sampled at their density, a random n_max 8 PSF of β 1.5 px), painted
//                          with stamps truncated at 10^−k of the noise rms σ:
//                          max_err_sigma  max |image − image at 10^−12| / σ (the stated bound
//                                         is 10^−k: the gap is how conservative it is)
//                          mean_side      mean stamp side, pixels
//   BM_Noise/kind          4096² of noise: 0 white, 1 correlated (F = 1.84), 2 white + photon
//                          noise over a field of objects (photon_tolerance 10^−3)
//                          ns_per_pixel
//   BM_SceneHdf            the HDF-sized image of issue 6: 4096² at 0.0398″ (2.72′ square),
//                          test::synthetic_morphology (HDF-like orders) at 700 per arcmin² plus
//                          10 stars, PSF n_max 10, correlated noise and photon noise, one
//                          thread; counters split the time: prepare_s (lensing none,
//                          convolution, stamp radii), paint_s, noise_s (writing the FITS file
//                          is left out: ~0.2 s for 64 MB)
#include "shapesim/polar.hpp"
#include "shapesim/sample.hpp"
#include "shapesim/scene.hpp"
#include "../unit/test_support.hpp"

#include <benchmark/benchmark.h>

#include <chrono>

using namespace shapesim;

namespace {

CartesianModel bench_psf(int n_max, double beta) {
    ShapeletModel psf = test::random_model(n_max, beta, 0.0, 0.0, 17, true, 0.15);
    const double f = flux(psf);
    for (auto& c : psf.coeffs) c /= f;
    return to_cartesian(psf);
}

std::vector<ObjectRecord> field_objects(const FieldGeometry& f, double density, int stars,
                                        bool heavy) {
    SampleOptions o;
    o.seed = 9;
    o.zero_point = 25.0;
    o.density = density;
    o.star_count = std::uint64_t(stars);
    o.stars.mag_min = 20.0;
    o.stars.mag_max = 26.0;
    std::vector<ObjectRecord> out;
    sample_field(test::synthetic_morphology(heavy), f, o, std::nullopt,
                 [&](const ObjectRecord& r) { out.push_back(r); });
    return out;
}

FieldGeometry square(int side, double scale) {
    FieldGeometry f;
    f.nx = f.ny = side;
    f.pixel_scale = scale;
    f.wcs = tan_wcs(150.0, 2.0, scale, 0.5 + side / 2.0, 0.5 + side / 2.0);
    return f;
}

std::vector<PreparedObject> prepare_all(const std::vector<ObjectRecord>& objects,
                                        const SceneKernels& k, const SceneOptions& o,
                                        double scale) {
    std::vector<PreparedObject> out;
    ConvolveWorkspace ws;
    for (const auto& r : objects) out.push_back(prepare_object(r, scale, k, o, &ws));
    return out;
}

void BM_SceneTruncation(benchmark::State& state) {
    const FieldGeometry f = square(1024, 0.04);
    const double area = f.area_arcmin2();
    const auto objects = field_objects(f, 1000.0 / area, 0, true);
    SceneKernels k;
    k.galaxy = k.star = bench_psf(8, 1.5);
    SceneOptions o;
    o.noise_rms = 1e-4;
    o.truncation = 1e-12;
    const Tile window{1, 1, 1024, 1024};
    const ImageArray reference = paint(prepare_all(objects, k, o, 0.04), window, o);
    o.truncation = std::pow(10.0, -double(state.range(0)));
    const auto prepared = prepare_all(objects, k, o, 0.04);
    ImageArray image;
    for (auto _ : state) {
        image = paint(prepared, window, o);
        benchmark::DoNotOptimize(image.data());
    }
    double side = 0.0;
    for (const auto& p : prepared) side += p.window.nx;
    state.counters["max_err_sigma"] = (image - reference).abs().maxCoeff() / o.noise_rms;
    state.counters["mean_side"] = side / double(prepared.size());
}
BENCHMARK(BM_SceneTruncation)->DenseRange(1, 6, 1)->Unit(benchmark::kMillisecond);

void BM_Noise(benchmark::State& state) {
    const int side = 4096;
    SceneOptions o;
    o.noise_rms = 2e-5;
    if (state.range(0) == 1) o.noise_correlation = 1.84;
    ImageArray signal = ImageArray::Zero(side, side);
    if (state.range(0) == 2) {
        o.gain = 865200.0;
        const FieldGeometry f = square(side, 0.0398);
        SceneKernels k;
        k.galaxy = k.star = bench_psf(10, 1.2);
        signal = paint(prepare_all(field_objects(f, 700.0, 10, false), k, o, 0.0398),
                       Tile{1, 1, side, side}, o);
    }
    const Tile window{1, 1, side, side};
    for (auto _ : state) {
        state.PauseTiming();
        ImageArray image = signal;
        state.ResumeTiming();
        add_noise(image, window, side, o);
        benchmark::DoNotOptimize(image.data());
    }
    // ns per pixel (Google Benchmark prints it with an "s" suffix: read it as ns).
    state.counters["ns_per_pixel"] = benchmark::Counter(
        double(side) * side / 1e9,
        benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_Noise)->DenseRange(0, 2, 1)->Unit(benchmark::kMillisecond)->Iterations(2);

// A fresh 4096² image zeroed, as paint() starts: range 0 an ordinary allocation, 1 large_image
// (2 MiB pages advised). The bytes are the same (error 0); the time is the kernel's page faults.
void BM_FreshImage(benchmark::State& state) {
    const long side = 4096;
    for (auto _ : state) {
        ImageArray image = state.range(0) ? large_image(side, side) : ImageArray(side, side);
        std::fill(image.data(), image.data() + image.size(), 0.0);
        benchmark::DoNotOptimize(image.data());
        state.counters["error"] = image.abs().maxCoeff();
    }
}
BENCHMARK(BM_FreshImage)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->Iterations(5);

// The HDF-sized scene's objects (700 per arcmin² and 10 stars over 4096² at 0.0398″) and its
// PSF (n_max 10).
struct HdfScene {
    std::vector<ObjectRecord> objects = field_objects(square(4096, 0.0398), 700.0, 10, false);
    SceneKernels kernels;
    HdfScene() { kernels.galaxy = kernels.star = bench_psf(10, 1.2); }
};

void BM_SceneHdf(benchmark::State& state) {
    const HdfScene scene;
    const auto& objects = scene.objects;
    const SceneKernels& k = scene.kernels;
    SceneOptions o;
    o.noise_rms = 2e-5;
    o.noise_correlation = 1.84;
    o.gain = 865200.0;
    const Tile window{1, 1, 4096, 4096};
    using clock = std::chrono::steady_clock;
    double prepare_s = 0.0, paint_s = 0.0, noise_s = 0.0;
    for (auto _ : state) {
        const auto t0 = clock::now();
        const auto prepared = prepare_all(objects, k, o, 0.0398);
        const auto t1 = clock::now();
        ImageArray image = paint(prepared, window, o);
        const auto t2 = clock::now();
        add_noise(image, window, 4096, o);
        const auto t3 = clock::now();
        benchmark::DoNotOptimize(image.data());
        prepare_s += std::chrono::duration<double>(t1 - t0).count();
        paint_s += std::chrono::duration<double>(t2 - t1).count();
        noise_s += std::chrono::duration<double>(t3 - t2).count();
    }
    const double n = double(state.iterations());
    state.counters["objects"] = double(objects.size());
    state.counters["prepare_s"] = prepare_s / n;
    state.counters["paint_s"] = paint_s / n;
    state.counters["noise_s"] = noise_s / n;
}
BENCHMARK(BM_SceneHdf)->Unit(benchmark::kMillisecond)->Iterations(2);

// BM_SceneHdfAccuracy/k  the HDF scene of BM_SceneHdf noise-free, stamps cut where every pixel
//                        left out is ≤ 10^−k of its model's central value (the peak-relative
//                        truncation), prepared and painted on one thread, against the same
//                        scene at 10^−12:
//                        max_err_rel_peak   max |image − reference| / the brightest centre
//                        flux_err_rel       Σ|image − reference| / Σ reference
//                        mean_side          mean stamp side, pixels
void BM_SceneHdfAccuracy(benchmark::State& state) {
    static const HdfScene scene;
    const auto& objects = scene.objects;
    const SceneKernels& k = scene.kernels;
    SceneOptions o;
    o.noise_free = true;
    o.truncation = 1e-12;
    const Tile window{1, 1, 4096, 4096};
    static const ImageArray reference = paint(prepare_all(objects, k, o, 0.0398), window, o);
    o.truncation = std::pow(10.0, -double(state.range(0)));
    ImageArray image;
    std::vector<PreparedObject> prepared;
    for (auto _ : state) {
        prepared = prepare_all(objects, k, o, 0.0398);
        image = paint(prepared, window, o);
        benchmark::DoNotOptimize(image.data());
    }
    double side = 0.0, peak = 0.0;
    for (const auto& p : prepared) {
        side += p.window.nx;
        peak = std::max(peak, truncation_threshold(p.model, o) / o.truncation);
    }
    state.counters["max_err_rel_peak"] = (image - reference).abs().maxCoeff() / peak;
    state.counters["flux_err_rel"] = (image - reference).abs().sum() / reference.sum();
    state.counters["mean_side"] = side / double(prepared.size());
}
BENCHMARK(BM_SceneHdfAccuracy)->DenseRange(3, 6, 1)->Unit(benchmark::kMillisecond)->Iterations(2);

}  // namespace

namespace {

// BM_LensingTolerance/k  prepare_object for 200 objects of the heavy morphology sheared by
//                        g = (0.05, −0.03), κ = 0.02, the lensed series truncated at relative
//                        error 10^−k: rel_err_max (of ‖g − P g‖²/‖g‖²), mean_n_out
void BM_LensingTolerance(benchmark::State& state) {
    const FieldGeometry f = square(1024, 0.04);
    auto objects = field_objects(f, 200.0 / f.area_arcmin2(), 0, true);
    SceneOptions o;
    o.noise_rms = 1e-4;
    o.lensing = Lensing{0.05, -0.03, 0.02, true};
    o.lensing_tolerance = std::pow(10.0, -double(state.range(0)));
    double worst = 0.0, orders = 0.0;
    std::size_t count = 0;
    for (auto _ : state) {
        worst = orders = 0.0;
        count = 0;
        ConvolveWorkspace ws;
        for (const auto& r : objects) {
            const PreparedObject p = prepare_object(r, 0.04, {}, o, &ws);
            worst = std::max(worst, p.lensing_error);
            orders += p.model.n_max;
            ++count;
        }
    }
    state.counters["rel_err_max"] = worst;
    state.counters["mean_n_out"] = orders / double(count);
}
BENCHMARK(BM_LensingTolerance)->DenseRange(2, 10, 2)->Unit(benchmark::kMillisecond);

// BM_PhotonTolerance/k   photon noise over the HDF-like field (4096², as BM_Noise/2) drawn
//                        only where its variance is ≥ 10^−k of the background's:
//                        variance_dropped  Σ s/g over the pixels left out / Σ s/g (k = 9: none)
void BM_PhotonTolerance(benchmark::State& state) {
    const int side = 4096;
    SceneOptions o;
    o.noise_rms = 2e-5;
    o.gain = 865200.0;
    o.photon_tolerance = state.range(0) >= 9 ? 0.0 : std::pow(10.0, -double(state.range(0)));
    const FieldGeometry f = square(side, 0.0398);
    SceneKernels k;
    k.galaxy = k.star = bench_psf(10, 1.2);
    static const ImageArray signal = paint(prepare_all(field_objects(f, 700.0, 10, false), k, o, 0.0398),
                                           Tile{1, 1, side, side}, o);
    const double floor = o.photon_tolerance * o.noise_rms * o.noise_rms;
    double all = 0.0, dropped = 0.0;
    for (Eigen::Index i = 0; i < signal.size(); ++i) {
        const double v = signal.data()[i] / o.gain;
        if (v <= 0.0) continue;
        all += v;
        if (v < floor) dropped += v;
    }
    for (auto _ : state) {
        state.PauseTiming();
        ImageArray image = signal;
        state.ResumeTiming();
        add_noise(image, Tile{1, 1, side, side}, side, o);
        benchmark::DoNotOptimize(image.data());
    }
    state.counters["variance_dropped"] = dropped / all;
}
BENCHMARK(BM_PhotonTolerance)->Arg(1)->Arg(2)->Arg(3)->Arg(5)->Arg(9)->Unit(benchmark::kMillisecond)->Iterations(2);

}  // namespace
