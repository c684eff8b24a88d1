// Rendering and fitting benchmarks: run time and the error each setting buys.
//   BM_RenderStamp/n_max/size        exact double render (error: vs brute-force quadrature of
//                                    the paper's formula on a sample of pixels)
//   BM_RenderStampFloat/n_max/size   the same product in float (error: vs the double render)
//   BM_RenderTruncated/n_max/k       stamp cut at k·β√(n_max+1): flux lost vs full stamp
//   BM_FitStamp/n_max/size           weighted least squares at fixed centre, β, n_max
//                                    (error: max coefficient error on a noise-free stamp)
#include "shapesim/basis1d.hpp"
#include "shapesim/lsq.hpp"
#include "shapesim/polar.hpp"
#include "shapesim/render.hpp"
#include "../unit/test_support.hpp"

#include <benchmark/benchmark.h>

#include <cmath>

using namespace shapesim;

namespace {
ShapeletModel bench_model(int n_max, double beta_pix, double centre) {
    return test::random_model(n_max, beta_pix, centre, centre + 0.37, 42 + n_max);
}

// β so that the model's extent β√(n_max+1) fills ~1/3 of the stamp, but never below a pixel.
double beta_for(int n_max, int size) { return std::max(1.0, size / (6.0 * std::sqrt(n_max + 1.0))); }

// Brute-force pixel integral of the polar formula (8×8 Gauss–Legendre points) at a pixel.
double brute_pixel(const ShapeletModel& model, int i, int j) {
    return test::integrate_pixel([&](double x, double y) { return evaluate(model, x, y); },
                                 i + 1, j + 1, 8);
}

void RenderArgs(benchmark::internal::Benchmark* b) {
    for (int n_max : {2, 4, 8, 15, 30})
        for (int size : {16, 32, 64, 128, 256}) b->Args({n_max, size});
}
}  // namespace

static void BM_RenderStamp(benchmark::State& state) {
    const int n_max = int(state.range(0)), size = int(state.range(1));
    const ShapeletModel model = bench_model(n_max, beta_for(n_max, size), size / 2.0);
    const CartesianModel cart = to_cartesian(model);
    ImageArray image = ImageArray::Zero(size, size);
    RenderWorkspace ws;
    for (auto _ : state) {
        image.setZero();
        add_to_image(cart, image, PixelWindow{0, 0, size, size}, ws);
        benchmark::DoNotOptimize(image.data());
    }
    // Error against brute force on a diagonal of pixels (the costly reference is not timed).
    double err = 0.0;
    for (int p = 0; p < size; p += std::max(1, size / 16))
        err = std::max(err, std::abs(image(p, p) - brute_pixel(model, p, p)));
    state.counters["max_err_rel_peak"] = err / image.abs().maxCoeff();
    state.counters["pixels_per_s"] =
        benchmark::Counter(double(size) * size, benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_RenderStamp)->Apply(RenderArgs);

static void BM_RenderStampFloat(benchmark::State& state) {
    const int n_max = int(state.range(0)), size = int(state.range(1));
    const ShapeletModel model = bench_model(n_max, beta_for(n_max, size), size / 2.0);
    const CartesianModel cart = to_cartesian(model);
    const Eigen::MatrixXf phi_x = pixel_basis_1d(n_max, cart.beta_pix, 1.0 - cart.x, size).cast<float>();
    const Eigen::MatrixXf phi_y = pixel_basis_1d(n_max, cart.beta_pix, 1.0 - cart.y, size).cast<float>();
    const Eigen::MatrixXf b = cart.b.cast<float>();
    Eigen::MatrixXf partial, block;
    for (auto _ : state) {
        partial.noalias() = b.transpose() * phi_x;
        block.noalias() = phi_y.transpose() * partial;
        benchmark::DoNotOptimize(block.data());
    }
    const ImageArray exact = render_stamp(cart, size, size);
    state.counters["max_err_rel_peak"] =
        (block.cast<double>().array() - exact.array()).abs().maxCoeff() / exact.abs().maxCoeff();
}
BENCHMARK(BM_RenderStampFloat)->Apply(RenderArgs);

static void BM_RenderTruncated(benchmark::State& state) {
    const int n_max = int(state.range(0));
    const double k = state.range(1) / 2.0;  // half-size in units of β√(n_max+1)
    const double beta = 2.0, full_half = 10.0 * beta * std::sqrt(n_max + 1.0);
    const int full = 2 * int(std::ceil(full_half)) + 1;
    const ShapeletModel model = bench_model(n_max, beta, full / 2.0 + 0.5);
    const CartesianModel cart = to_cartesian(model);
    const int half = int(std::ceil(k * beta * std::sqrt(n_max + 1.0)));
    const int c = full / 2;
    const PixelWindow window{c - half, c - half, 2 * half + 1, 2 * half + 1};
    ImageArray image = ImageArray::Zero(full, full);
    RenderWorkspace ws;
    for (auto _ : state) {
        image.setZero();
        add_to_image(cart, image, window, ws);
        benchmark::DoNotOptimize(image.data());
    }
    const ImageArray exact = render_stamp(cart, full, full);
    state.counters["stamp_side"] = 2 * half + 1;
    state.counters["max_err_rel_peak"] = (image - exact).abs().maxCoeff() / exact.abs().maxCoeff();
    state.counters["flux_lost_rel"] = std::abs(exact.sum() - image.sum()) / std::abs(exact.sum());
}
BENCHMARK(BM_RenderTruncated)->ArgsProduct({{4, 8, 15}, {2, 3, 4, 6, 8}});

static void BM_FitStamp(benchmark::State& state) {
    const int n_max = int(state.range(0)), size = int(state.range(1));
    const double beta = beta_for(n_max, size);
    const ShapeletModel truth = bench_model(n_max, beta, size / 2.0);
    const ImageArray image = render_stamp(truth, size, size);
    const ImageArray weight = ImageArray::Ones(size, size);
    ShapeletFit fit;
    for (auto _ : state) {
        fit = fit_shapelets(image, weight, nullptr, truth.x, truth.y, beta, n_max);
        benchmark::DoNotOptimize(fit.chi2);
    }
    const Eigen::VectorXd a = real_parameters(fit.model), t = real_parameters(truth);
    state.counters["max_coeff_err_rel"] = (a - t).cwiseAbs().maxCoeff() / t.cwiseAbs().maxCoeff();
}
BENCHMARK(BM_FitStamp)->ArgsProduct({{2, 4, 8, 15}, {32, 64, 128}});
