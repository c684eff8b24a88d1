// Shear and translation re-projections: run time and the error they buy (DESIGN §1, STYLE
// "Tests"). A galaxy-like model (a00 = 1, others ~0.35 e^{−n/5}, β = 2 px) at n_in 8 and 15,
// sheared by g = (0.2, 0.1) or moved by (1.0, 0.6) px, projected to n_out = n_in + {0, 4, 8, 16}
// and to the automatic order (tolerance 1e-10). Counters:
//   rel_error  ‖g − P_N g‖² / ‖g‖², the exact (Parseval) truncation error of the result;
//   n_out      the output order (useful for the automatic case).
// The workspace is reused across iterations, as a sampler transforming many objects would.
#include "shapesim/transform.hpp"

#include "../unit/test_support.hpp"

#include <benchmark/benchmark.h>

using namespace shapesim;

namespace {

ShapeletModel bench_model(int n_max) {
    return test::random_model(n_max, 2.0, 50.3, 60.7, 1234 + n_max);
}

/// range(0) = n_in, range(1) = n_out − n_in, or −1 for the automatic order.
ProjectionOptions bench_options(const benchmark::State& state) {
    ProjectionOptions options;
    if (state.range(1) >= 0) options.n_out = int(state.range(0) + state.range(1));
    return options;
}

/// Times `project(model, options, workspace)` on bench_model(range(0)) and reports the result.
template <class Project>
void run_projection(benchmark::State& state, Project project) {
    const ShapeletModel model = bench_model(int(state.range(0)));
    const ProjectionOptions options = bench_options(state);
    ProjectionWorkspace ws;
    Projection p;
    for (auto _ : state) {
        p = project(model, options, &ws);
        benchmark::DoNotOptimize(p.model.coeffs.data());
    }
    state.counters["rel_error"] = p.relative_error;
    state.counters["n_out"] = p.model.n_max;
}

void BM_Shear(benchmark::State& state) {
    run_projection(state, [](const auto& m, const auto& o, auto* ws) {
        return shear(m, 0.2, 0.1, o, ws);
    });
}

void BM_Translate(benchmark::State& state) {
    run_projection(state, [](const auto& m, const auto& o, auto* ws) {
        return translate(m, 1.0, 0.6, o, ws);
    });
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
