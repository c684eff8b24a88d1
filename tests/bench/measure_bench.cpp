// Measurement benchmarks: run time and the error it buys.
//   BM_ExactAperture/shape/sep/radius  one exact aperture sum (subpix 0) on a 256² image of
//                          random values, at 64 random centres: shape 0 a circle, 1 an ellipse
//                          (axis ratio 2, θ = 0.6); sep 0 ours (exact_aperture.hpp), 1 libsep's
//                          sep_sum_circle / sep_sum_ellipse; radius the semi-major axis in pixels.
//                          ns_per_sum    time per aperture (printed with an "s" or "ks" suffix:
//                                        an inverted rate; 1.5ks is 1500 ns)
//                          max_diff      ours: the largest |ours − sep| over the centres, as a
//                                        share of sep's sum of |values| in the aperture (sep: 0)
//   BM_MorphometryStatmorph  measure_morphometry on statmorph's reference galaxy (its test
//                          suite's image, segmentation and mask; 164² pixels).
//                          ms_per_galaxy time per galaxy
//                          r_petro_rel   |r_p / statmorph's − 1|
//                          c_rel         |C / statmorph's − 1|
//                          a_abs         |A − statmorph's|
//                          gini_abs      |Gini − statmorph's|
#include "shapesim/exact_aperture.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/morphometry.hpp"
#include "../unit/test_support.hpp"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

using namespace shapesim;

namespace {

constexpr int kSide = 256;
constexpr double kAxisRatio = 2.0, kTheta = 0.6;

struct ApertureCase {
    std::vector<double> data, magnitude;
    std::vector<double> x, y;
};

const ApertureCase& aperture_case() {
    static const ApertureCase c = [] {
        ApertureCase out;
        std::mt19937_64 rng(20261128);
        std::uniform_real_distribution<double> unit(0.0, 1.0);
        out.data.resize(std::size_t(kSide) * kSide);
        for (double& v : out.data) v = unit(rng) - 0.3;
        for (double v : out.data) out.magnitude.push_back(std::abs(v));
        for (int k = 0; k < 64; ++k) {
            out.x.push_back(64.0 + 128.0 * unit(rng));
            out.y.push_back(64.0 + 128.0 * unit(rng));
        }
        return out;
    }();
    return c;
}

double sep_sum(const std::vector<double>& data, bool ellipse, double x, double y, double a) {
    return ellipse ? test::sep_ellipse_sum(data, kSide, kSide, x, y, a, a / kAxisRatio, kTheta)
                   : test::sep_circle_sum(data, kSide, kSide, x, y, a);
}

double our_sum(const std::vector<double>& data, bool ellipse, double x, double y, double a) {
    return ellipse ? sum_ellipse(data.data(), kSide, kSide, x, y, a, a / kAxisRatio, kTheta)
                   : sum_circle(data.data(), kSide, kSide, x, y, a);
}

void BM_ExactAperture(benchmark::State& state) {
    const bool ellipse = state.range(0) == 1, sep = state.range(1) == 1;
    const double a = double(state.range(2));
    const ApertureCase& c = aperture_case();
    double max_diff = 0.0;
    for (std::size_t k = 0; k < c.x.size(); ++k) {
        const double want = sep_sum(c.data, ellipse, c.x[k], c.y[k], a);
        const double got = our_sum(c.data, ellipse, c.x[k], c.y[k], a);
        const double scale = sep_sum(c.magnitude, ellipse, c.x[k], c.y[k], a);
        max_diff = std::max(max_diff, std::abs(got - want) / scale);
    }
    double sink = 0.0;
    for (auto _ : state)
        for (std::size_t k = 0; k < c.x.size(); ++k)
            sink += sep ? sep_sum(c.data, ellipse, c.x[k], c.y[k], a)
                        : our_sum(c.data, ellipse, c.x[k], c.y[k], a);
    benchmark::DoNotOptimize(sink);
    // Seconds per (sums × 1e-9): nanoseconds per sum.
    state.counters["ns_per_sum"] =
        benchmark::Counter(1e-9 * double(c.x.size()),
                           benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
    state.counters["max_diff"] = sep ? 0.0 : max_diff;
}
BENCHMARK(BM_ExactAperture)
    ->ArgsProduct({{0, 1}, {0, 1}, {3, 12, 48}})
    ->ArgNames({"ellipse", "sep", "a"})
    ->Unit(benchmark::kMicrosecond);

void BM_MorphometryStatmorph(benchmark::State& state) {
    FitsReader fits(shapesim::test::source_dir() + "/tests/data/statmorph/slice.fits");
    fits.move_to(0);
    const ImageArray image = fits.read_image();
    fits.move_to(1);
    const LabelArray labels = fits.read_image().cast<std::int32_t>();
    fits.move_to(2);
    const MaskArray mask = (fits.read_image() != 0.0).cast<std::uint8_t>();
    Morphometry m;
    for (auto _ : state) {
        m = measure_morphometry(image, labels, 1, &mask);
        benchmark::DoNotOptimize(m.asymmetry);
    }
    // statmorph's test-suite values (tests/data/statmorph/README.md).
    state.counters["ms_per_galaxy"] = benchmark::Counter(
        1e-3, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
    state.counters["r_petro_rel"] = std::abs(m.r_petro / 40.93755531944313 - 1.0);
    state.counters["c_rel"] = std::abs(m.concentration / 2.19100140632153 - 1.0);
    state.counters["a_abs"] = std::abs(m.asymmetry - 0.00377345808887);
    state.counters["gini_abs"] = std::abs(m.gini - 0.38993180299621);
}
BENCHMARK(BM_MorphometryStatmorph)->Unit(benchmark::kMillisecond);

}  // namespace
