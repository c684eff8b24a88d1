// Exact shapelet convolution: run time and the error it buys (DESIGN §1, STYLE "Tests").
// Cases (n_gal, n_psf) = (4,4), (8,8), (15,8), (30,8). Counters:
//   error      max |Σ_l C_nml B_l(x;γ) − ∫ B_n B_m| over sample points (1D tensor), or
//              max |h − brute| / max |h| against a lattice-sum convolution of the point-sampled
//              models (2D), both computed once outside the timed loop;
//   ref_error  max over convolved.jsonl of max|Δa| / max|a| (README tolerance 1e-10).
#include "shapesim/convolve.hpp"

#include "shapesim/polar.hpp"
#include "../unit/test_support.hpp"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <vector>

using namespace shapesim;

namespace {

// Scales chosen like real fits: the galaxy basis resolves ≥ 1 px, the PSF β ~ 1.5 px.
constexpr double kPsfBeta = 1.5;
double galaxy_beta(int n_max) { return std::max(1.2, 0.5 * std::sqrt(n_max + 1.0)); }

// A galaxy-like model (test_support) at a fixed sub-pixel centre.
ShapeletModel random_model(int n_max, double beta, unsigned seed) {
    return test::random_model(n_max, beta, 50.3, 60.7, seed);
}

// 1D check of the tensor (test_support): trapezoid sum of B_n(x′; α) B_m(x − x′; b) at a few x.
double tensor_error(const ConvolutionTensor& c) {
    const double half_width = 12.0 * std::max(c.alpha(), c.b()) * 1.5;
    return test::tensor_brute_force_error(c, {-1.7, 0.3, 2.9}, 0.02, half_width);
}

// 2D check (test_support): lattice sum δ² Σ f(x_i) g(x − x_i) of the point-sampled models.
double brute_force_error(const ShapeletModel& f, const ShapeletModel& g, const ShapeletModel& h) {
    return test::lattice_convolution_error(f, g, h, 0.25, 20, 20, 5);
}

void convolve_cases(benchmark::internal::Benchmark* b) {
    for (const auto& [n_f, n_g] : {std::pair{4, 4}, {8, 8}, {15, 8}, {30, 8}}) b->Args({n_f, n_g});
}

void BM_ConvolutionTensor(benchmark::State& state) {
    const int n_f = int(state.range(0)), n_g = int(state.range(1));
    const double alpha = galaxy_beta(n_f);
    for (auto _ : state) {
        ConvolutionTensor c(alpha, kPsfBeta, n_f, n_g);
        benchmark::DoNotOptimize(c(0, 0, 0));
    }
    state.counters["error"] = tensor_error(ConvolutionTensor(alpha, kPsfBeta, n_f, n_g));
}
BENCHMARK(BM_ConvolutionTensor)->Apply(convolve_cases)->Unit(benchmark::kMicrosecond);

// The per-galaxy work for a fixed PSF (already Cartesian) with a reusable workspace.
void BM_ConvolveCartesian(benchmark::State& state) {
    const int n_f = int(state.range(0)), n_g = int(state.range(1));
    const ShapeletModel f = random_model(n_f, galaxy_beta(n_f), 1);
    const ShapeletModel g = random_model(n_g, kPsfBeta, 2);
    const CartesianModel fc = to_cartesian(f), gc = to_cartesian(g);
    ConvolveWorkspace ws;
    for (auto _ : state) benchmark::DoNotOptimize(convolve(fc, gc, ws).b.data());
    state.counters["error"] = brute_force_error(f, g, convolve(f, g));
}
BENCHMARK(BM_ConvolveCartesian)->Apply(convolve_cases)->Unit(benchmark::kMicrosecond);

// Polar in, polar out (two conversions to Cartesian and one back, all exact).
void BM_ConvolvePolar(benchmark::State& state) {
    const int n_f = int(state.range(0)), n_g = int(state.range(1));
    const ShapeletModel f = random_model(n_f, galaxy_beta(n_f), 3);
    const ShapeletModel g = random_model(n_g, kPsfBeta, 4);
    for (auto _ : state) benchmark::DoNotOptimize(convolve(f, g).coeffs.data());
}
BENCHMARK(BM_ConvolvePolar)->Apply(convolve_cases)->Unit(benchmark::kMicrosecond);

// The linear map for fitting PSF-convolved models (per galaxy β and n_max).
void BM_ConvolutionMatrix(benchmark::State& state) {
    const int n_f = int(state.range(0)), n_g = int(state.range(1));
    const ShapeletModel g = random_model(n_g, kPsfBeta, 5);
    for (auto _ : state) benchmark::DoNotOptimize(convolution_matrix(g, galaxy_beta(n_f), n_f));
}
BENCHMARK(BM_ConvolutionMatrix)->Apply(convolve_cases)->Unit(benchmark::kMicrosecond);

// Deconvolution back to the galaxy's order; error = max|Δa|/max|a| of the recovered galaxy.
void BM_Deconvolve(benchmark::State& state) {
    const int n_f = int(state.range(0)), n_g = int(state.range(1));
    const ShapeletModel f = random_model(n_f, galaxy_beta(n_f), 6);
    const ShapeletModel g = random_model(n_g, kPsfBeta, 7);
    const ShapeletModel h = convolve(f, g);
    InverseReport report;
    for (auto _ : state) benchmark::DoNotOptimize(deconvolve(h, g, n_f, &report).coeffs.data());
    const ShapeletModel back = deconvolve(h, g, n_f, &report);
    state.counters["error"] = (real_parameters(back) - real_parameters(f)).cwiseAbs().maxCoeff() /
                              real_parameters(f).cwiseAbs().maxCoeff();
    state.counters["condition"] = report.condition_number;
}
BENCHMARK(BM_Deconvolve)->Apply(convolve_cases)->Unit(benchmark::kMillisecond);

// The 8 GalSim reference pairs of convolved.jsonl (test_support, as the unit tests read them).
void BM_ConvolveReference(benchmark::State& state) {
    const std::vector<test::ReferenceConvolution>* refs = nullptr;
    try {
        refs = &test::reference_convolutions();
    } catch (const std::exception& e) {
        state.SkipWithError(e.what());
        return;
    }
    for (auto _ : state)
        for (const auto& r : *refs)
            benchmark::DoNotOptimize(convolve(r.galaxy, r.psf).coeffs.data());
    double worst = 0.0;
    for (const auto& r : *refs) {
        const Eigen::VectorXd a = real_parameters(r.result);
        const Eigen::VectorXd d = real_parameters(convolve(r.galaxy, r.psf)) - a;
        worst = std::max(worst, d.cwiseAbs().maxCoeff() / a.cwiseAbs().maxCoeff());
    }
    state.counters["ref_error"] = worst;
    state.counters["pairs"] = double(refs->size());
}
BENCHMARK(BM_ConvolveReference)->Unit(benchmark::kMicrosecond);

}  // namespace
