// Sampling benchmarks (morphology.hpp, sample.hpp): objects per second, and what each draw
// bought. Two morphologies of 200 galaxy-like random models (test::random_model, a_00 = 1,
// others ~0.2·e^{−n/5}), β 1–5 px at 0.04″, magnitudes 22–29, λ's by the default rule (k = 4,
// 15°): "hdf" with the n_max of the HDF cut's smoothed models (147 of 160 at 0, the rest
// 2–7), "heavy" with n_max = k mod 16 (0–15, mean 7.5).
//   BM_DrawGalaxy/heavy/delta  one draw_galaxy(): parent, perturbation of every axis, rebuild at
//                         the drawn flux, rotation and flip (delta = 1: the δ-function PDF)
//                         redraw_frac     perturbations refused (non-positive flux, β ≤ 0,
//                                         too faint) per draw
//                         perturbation    mean ‖c' − c‖/‖c‖ (0 for δ)
//   BM_SampleField/json   sample_field() over a 1 arcmin² field at 700 per arcmin² ("hdf"), records
//                         built (json = 1: and serialised as the program writes them)
//   BM_SampleTile         the same field, one tile of 1/16 of it: objects beyond the widest
//                         reach skip the shape draw
#include "shapesim/moments.hpp"
#include "shapesim/morphology.hpp"
#include "shapesim/sample.hpp"
#include "../unit/test_support.hpp"

#include <benchmark/benchmark.h>

using namespace shapesim;

namespace {

const Morphology& bench_morphology(bool heavy = false) {
    static const Morphology hdf = test::synthetic_morphology(false),
                            many = test::synthetic_morphology(true);
    return heavy ? many : hdf;
}

FieldGeometry square_field(double arcmin) {
    FieldGeometry f;
    f.pixel_scale = 0.04;
    f.nx = f.ny = int(arcmin * 60.0 / 0.04);
    f.wcs = tan_wcs(150.0, 2.0, 0.04, 0.5 + f.nx / 2.0, 0.5 + f.ny / 2.0);
    return f;
}

void BM_DrawGalaxy(benchmark::State& state) {
    Morphology m = bench_morphology(state.range(0) != 0);
    if (state.range(1)) {
        m.lambda.phase_deg = m.lambda.beta = m.lambda.mag = 0.0;
        std::fill(m.lambda.coefficient.begin(), m.lambda.coefficient.end(), 0.0);
    }
    const std::vector<double> parents = parent_table(m, 29.0);
    std::uint64_t k = 0, redraws = 0;
    double perturbation = 0.0;
    for (auto _ : state) {
        RandomStream stream(7, k++, "galaxy");
        const DrawnGalaxy g = draw_galaxy(m, parents, stream, 0.04, 25.0, 29.0);
        redraws += std::uint64_t(g.redraws);
        perturbation += g.perturbation;
        benchmark::DoNotOptimize(g.model.coeffs.data());
    }
    state.SetItemsProcessed(std::int64_t(k));
    state.counters["redraw_frac"] = double(redraws) / double(k);
    state.counters["perturbation"] = perturbation / double(k);
}
BENCHMARK(BM_DrawGalaxy)->ArgNames({"heavy", "delta"})->Args({0, 0})->Args({0, 1})->Args({1, 0})->Args({1, 1});

void BM_SampleField(benchmark::State& state) {
    const Morphology& m = bench_morphology();
    const FieldGeometry f = square_field(1.0);
    SampleOptions o;
    o.seed = 3;
    o.zero_point = 25.0;
    std::int64_t items = 0;
    std::size_t bytes = 0;
    for (auto _ : state) {
        o.seed++;
        const SampleSummary s = sample_field(m, f, o, std::nullopt, [&](const ObjectRecord& r) {
            if (state.range(0)) bytes += r.to_json().dump().size();
            else benchmark::DoNotOptimize(r.coeffs.data());
        });
        items += std::int64_t(s.galaxies_out);
    }
    state.SetItemsProcessed(items);
    if (state.range(0)) state.counters["bytes_per_object"] = double(bytes) / double(items);
}
BENCHMARK(BM_SampleField)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

void BM_SampleTile(benchmark::State& state) {
    const Morphology& m = bench_morphology();
    const FieldGeometry f = square_field(1.0);
    SampleOptions o;
    o.seed = 3;
    o.zero_point = 25.0;
    const Tile t{1, 1, f.nx / 4, f.ny / 4};
    std::int64_t out = 0, drawn = 0;
    for (auto _ : state) {
        const SampleSummary s = sample_field(m, f, o, t, [&](const ObjectRecord&) {});
        out += std::int64_t(s.galaxies_out);
        drawn += std::int64_t(s.galaxies);
    }
    state.SetItemsProcessed(drawn);
    state.counters["in_tile_frac"] = double(out) / double(drawn);
}
BENCHMARK(BM_SampleTile)->Unit(benchmark::kMillisecond);

}  // namespace
