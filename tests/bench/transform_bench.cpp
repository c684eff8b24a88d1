// Shear and translation re-projections: run time and the error they buy (DESIGN §1, STYLE
// "Tests"). A galaxy-like model (a00 = 1, others ~0.35 e^{−n/5}, β = 2 px) at n_in 8 and 15,
// sheared by g = (0.2, 0.1) or moved by (1.0, 0.6) px, projected to n_out = n_in + {0, 4, 8, 16}
// and to the automatic order (tolerance 1e-10). Counters:
//   rel_error  ‖g − P_N g‖² / ‖g‖², the exact (Parseval) truncation error of the result;
//   n_out      the output order (useful for the automatic case).
// The workspace is reused across iterations, as a sampler transforming many objects would.
#include "shapesim/transform.hpp"

#include "shapesim/polar.hpp"

#include <benchmark/benchmark.h>

#include <cmath>
#include <random>

using namespace shapesim;

namespace {

ShapeletModel bench_model(int n_max) {
    std::mt19937_64 rng(1234 + n_max);
    std::normal_distribution<double> normal;
    ShapeletModel model(50.3, 60.7, 2.0, n_max);
    for (const auto& [n, m] : polar_indices(n_max)) {
        const double sigma = 0.35 * std::exp(-n / 5.0);
        model.at(n, m) = Complex(sigma * normal(rng), m == 0 ? 0.0 : sigma * normal(rng));
    }
    model.at(0, 0) = 1.0;
    return model;
}

/// range(0) = n_in, range(1) = n_out − n_in, or −1 for the automatic order.
ProjectionOptions bench_options(const benchmark::State& state) {
    ProjectionOptions options;
    if (state.range(1) >= 0) options.n_out = int(state.range(0) + state.range(1));
    return options;
}

void report(benchmark::State& state, const Projection& p) {
    state.counters["rel_error"] = p.relative_error;
    state.counters["n_out"] = p.model.n_max;
}

void BM_Shear(benchmark::State& state) {
    const ShapeletModel model = bench_model(int(state.range(0)));
    const ProjectionOptions options = bench_options(state);
    ProjectionWorkspace ws;
    Projection p;
    for (auto _ : state) {
        p = shear(model, 0.2, 0.1, options, &ws);
        benchmark::DoNotOptimize(p.model.coeffs.data());
    }
    report(state, p);
}

void BM_Translate(benchmark::State& state) {
    const ShapeletModel model = bench_model(int(state.range(0)));
    const ProjectionOptions options = bench_options(state);
    ProjectionWorkspace ws;
    Projection p;
    for (auto _ : state) {
        p = translate(model, 1.0, 0.6, options, &ws);
        benchmark::DoNotOptimize(p.model.coeffs.data());
    }
    report(state, p);
}

// Exact phase rotation, for scale.
void BM_Rotate(benchmark::State& state) {
    const ShapeletModel model = bench_model(int(state.range(0)));
    for (auto _ : state) benchmark::DoNotOptimize(rotate(model, 0.7).coeffs.data());
}

void projection_args(benchmark::internal::Benchmark* b) {
    for (int n_in : {8, 15})
        for (int extra : {0, 4, 8, 16, -1}) b->Args({n_in, extra});
    b->Unit(benchmark::kMicrosecond);
}

}  // namespace

BENCHMARK(BM_Shear)->Apply(projection_args);
BENCHMARK(BM_Translate)->Apply(projection_args);
BENCHMARK(BM_Rotate)->Arg(8)->Arg(15)->Unit(benchmark::kMicrosecond);
