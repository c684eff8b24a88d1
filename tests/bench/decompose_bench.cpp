// Decomposition benchmarks (lsq.hpp, decompose.hpp): run time and the error it buys.
// Test galaxies are test::random_model galaxies (a_00 = 1, others ~0.35·e^{−n/5}) rendered
// pixel-integrated, plus white Gaussian noise from RandomStream(seed, object, "noise") of σ a
// fixed fraction of the peak pixel (peak S/N), weights 1/σ².
//   BM_FitFixed/n_max/side   one fit_shapelets at the true centre, β and n_max (peak S/N 100;
//                            β fills a third of the stamp, as in BM_FitStamp, ≥ 1 px)
//                            coeff_err_rel  ‖p_fit − p_true‖ / ‖p_true‖ (real parameter vector)
//                            coeff_err_pred the same predicted by the covariance,
//                                           √tr(C) / ‖p_true‖: the fit is at its noise floor
//                                           when the two agree
//                            chi2r          χ²_r of the fit (≈ 1 ± √(2/dof))
//                            solver_qr      1 when the QR fallback was used
//   BM_Decompose/n_max_true/side  a full decompose() (centre, β, n_max free; default options)
//                            of one galaxy of order n_max_true with a_{n,±1} = 0 (centred,
//                            below), β_true = 1.25·√(n_max_true+1)·side/32 px (θ_min = 1.25
//                            px·side/32; the model spans ~40% of the half-stamp), peak S/N
//                            100, start centre (0.3, −0.2) px off the truth; the iterations
//                            cycle through 4 noise realisations and the counters average them:
//                            n_max          mean fitted order (truth in the name)
//                            chi2r          mean effective χ²_r of the fit kept
//                            flux_err_rel   rms of (F_fit − F_true) / F_true
//                            flux_pull_rms  rms of (F_fit − F_true) / the reported flux error
//                                           (≈ 1 when that error is right)
//                            fits           mean linear fits performed (Decomposition::fits)
//   BM_DecomposeTolerance/neg_log10_tol/chi2_sigmas  the same 12 centred galaxies
//                            (n_true = 0…8 and 0…2, β_true in [1.2, 1.6]·√(n_true+1) px, 48²
//                            stamps, peak S/N log-uniform in [20, 300]) decomposed with
//                            beta_tolerance 10^−neg_log10_tol and chi2_sigmas as given: the
//                            run-time/error curve
//                            chi2r_mean      mean effective χ²_r
//                            flux_err_rel    mean |F_fit − F_true| / F_true
//                            n_max_abs_err   mean |n_max − n_true|
//                            fits_mean       mean linear fits per galaxy
//                            converged_frac  fraction that reached the χ²_r target
//   BM_DecomposeHdf          every stamp of the shipped 512² HDF-N F814W cut, as
//                            shapesim-decompose fits them (detect_sources + cut_stamp with
//                            default options, done once outside the timed loop; the
//                            field's correlated-noise factor; neighbours masked; start at the
//                            detection's centre and a), single-threaded:
//                            objects, fitted (the rest threw), converged_frac, median_n_max,
//                            fits_mean, time_per_object (s per stamp)
//
// Against GalSim. GalSim's Shapelet.fit (ShapeletFitImage: the full pixels × coefficients
// design, point-sampled, unweighted, column-pivoting QR, no covariance) on a 64² stamp takes on
// this machine 0.29 ms at order 4, 1.4 ms at order 8 and 11.7 ms at order 15.
// BM_FitFixed/·/64 does more (pixel-integrated basis, weights, the full covariance, model and
// residual images) in 0.15–0.19 ms, 0.36–0.52 ms and 2.7–4.2 ms (CPU time, ranges over runs on
// this shared 2-core machine): 1.5–1.9×, 2.7–3.9× and 2.8–4.3× faster, the normal matrix built
// separably (lsq.hpp) rather than from the side² × coefficients design. The coefficient errors
// equal their covariance prediction (coeff_err_rel ≈ coeff_err_pred): the fits are at their
// noise floor, also at order 15 on 32² where β = 1.33 px and the finest scale β/4 is a third
// of a pixel (the error is large there because the data cannot constrain those coefficients).
#include "shapesim/decompose.hpp"
#include "shapesim/detect.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/lsq.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/render.hpp"
#include "shapesim/rng.hpp"
#include "shapesim/stamps.hpp"
#include "../unit/test_support.hpp"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <exception>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

using namespace shapesim;

namespace {

constexpr double nan = std::numeric_limits<double>::quiet_NaN();
const std::string kSource = shapesim::test::source_dir();
const std::string kHdfImage = kSource + "/share/data/hdfn/hdfn_f814w_v2.fits";
const std::string kHdfWeight = kSource + "/share/data/hdfn/hdfn_f814w_v2_weight.fits";
constexpr int kNoiseRealisations = 4;  // BM_Decompose

// A rendered galaxy with noise, and the truth.
struct NoisyGalaxy {
    ShapeletModel truth;
    ImageArray image, weight;
    double sigma = 0.0;
};

// `truth` rendered on a side² stamp plus white noise of σ = peak / peak_snr.
// The noise stream is keyed by (seed, object).
NoisyGalaxy noisy_galaxy(const ShapeletModel& truth, int side, double peak_snr,
                         std::uint64_t seed, std::uint64_t object) {
    NoisyGalaxy g;
    g.truth = truth;
    g.image = render_stamp(truth, side, side);
    g.sigma = g.image.abs().maxCoeff() / peak_snr;
    RandomStream noise(seed, object, "noise");
    for (Eigen::Index j = 0; j < g.image.rows(); ++j)
        for (Eigen::Index i = 0; i < g.image.cols(); ++i)
            g.image(j, i) += g.sigma * noise.gaussian();
    g.weight = ImageArray::Constant(side, side, 1.0 / (g.sigma * g.sigma));
    return g;
}

// (The timed loops hand DoNotOptimize a pointer, read-only: with GCC, benchmark 1.7's "+m,r"
// form on a double lvalue can leave garbage in it, google/benchmark#903, GCC PR 92597.)

// The stamp's FITS centre, a little off the pixel grid.
double centre_of(int side) { return (side + 1) / 2.0 + 0.23; }

// A test::random_model galaxy with a_{n,±1} = 0, so that its centroid is its basis centre:
// the centre decompose() converges to (a galaxy with a dipole about its basis centre needs a
// higher order about its centroid, and would not test the choice of n_max).
ShapeletModel centred_model(int n_max, double beta_pix, double x, double y, unsigned seed) {
    ShapeletModel m = test::random_model(n_max, beta_pix, x, y, seed);
    for (int n = 1; n <= n_max; n += 2) m.at(n, 1) = Complex(0.0, 0.0);
    return m;
}

double relative_flux_error(const ShapeletModel& fitted, const ShapeletModel& truth) {
    const double f = flux(truth);
    return std::abs(flux(fitted) - f) / std::abs(f);
}

// ---------------------------------------------------------------------------------------------
// One linear fit at fixed centre, β, n_max.

void BM_FitFixed(benchmark::State& state) {
    const int n_max = int(state.range(0)), side = int(state.range(1));
    const double beta = std::max(1.0, side / (6.0 * std::sqrt(n_max + 1.0)));
    const double c = centre_of(side);
    const NoisyGalaxy g =
        noisy_galaxy(test::random_model(n_max, beta, c, c - 0.41, 7 + unsigned(n_max)), side,
                     100.0, 11, std::uint64_t(100 * n_max + side));
    ShapeletFit fit;
    try {
        for (auto _ : state) {
            fit = fit_shapelets(g.image, g.weight, nullptr, g.truth.x, g.truth.y, beta, n_max);
            benchmark::DoNotOptimize(fit.model.coeffs.data());
        }
    } catch (const std::exception& e) {
        state.SkipWithError(e.what());
        return;
    }
    const Eigen::VectorXd p = real_parameters(fit.model), t = real_parameters(g.truth);
    state.counters["coeff_err_rel"] = (p - t).norm() / t.norm();
    state.counters["coeff_err_pred"] = std::sqrt(fit.covariance.trace()) / t.norm();
    state.counters["chi2r"] = fit.chi2r;
    state.counters["solver_qr"] = fit.solver_used == LsqSolver::qr ? 1.0 : 0.0;
}
BENCHMARK(BM_FitFixed)->ArgsProduct({{4, 8, 15}, {32, 64}})->ArgNames({"n_max", "side"})
    ->Unit(benchmark::kMicrosecond);

// ---------------------------------------------------------------------------------------------
// A full decomposition of one galaxy.

void BM_Decompose(benchmark::State& state) {
    const int n_true = int(state.range(0)), side = int(state.range(1));
    const double beta = 1.25 * std::sqrt(n_true + 1.0) * side / 32.0;
    const double c = centre_of(side);
    const ShapeletModel truth = centred_model(n_true, beta, c, c - 0.41, 100 + unsigned(n_true));
    // One galaxy, kNoiseRealisations noise fields: the iterations cycle through them.
    std::vector<NoisyGalaxy> g;
    for (int r = 0; r < kNoiseRealisations; ++r)
        g.push_back(noisy_galaxy(truth, side, 100.0, 12, std::uint64_t(1000 * r + side)));
    const DecomposeOptions options;
    std::vector<std::optional<Decomposition>> d(g.size());
    const auto run = [&](std::size_t r) {
        d[r] = decompose(g[r].image, g[r].weight, nullptr, truth.x + 0.3, truth.y - 0.2, beta,
                         options);
    };
    try {
        std::size_t r = 0;
        for (auto _ : state) {
            run(r);
            benchmark::DoNotOptimize(d[r]->fit.model.coeffs.data());
            r = (r + 1) % g.size();
        }
        for (std::size_t k = 0; k < g.size(); ++k)
            if (!d[k]) run(k);  // the realisations the timed loop did not reach
    } catch (const std::exception& e) {
        state.SkipWithError(e.what());
        return;
    }
    const double f_true = flux(truth), n = double(g.size());
    double n_max = 0.0, chi2r = 0.0, flux_err2 = 0.0, pull2 = 0.0, fits = 0.0;
    for (const auto& x : d) {
        n_max += x->fit.model.n_max;
        chi2r += x->chi2r;
        const double f = flux(x->fit.model);
        flux_err2 += (f - f_true) * (f - f_true) / (f_true * f_true);
        pull2 += (f - f_true) * (f - f_true) / (x->flux_error * x->flux_error);
        fits += double(x->fits);
    }
    state.counters["n_max"] = n_max / n;
    state.counters["chi2r"] = chi2r / n;
    state.counters["flux_err_rel"] = std::sqrt(flux_err2 / n);
    state.counters["flux_pull_rms"] = std::sqrt(pull2 / n);
    state.counters["fits"] = fits / n;
}
BENCHMARK(BM_Decompose)->ArgsProduct({{2, 5, 8}, {32, 64}})->ArgNames({"n_max_true", "side"})
    ->Unit(benchmark::kMillisecond);

// ---------------------------------------------------------------------------------------------
// The β tolerance and the χ²_r allowance against fit quality, on a fixed set of galaxies.

const std::vector<NoisyGalaxy>& tolerance_galaxies() {
    static const std::vector<NoisyGalaxy> set = [] {
        constexpr int side = 48, count = 12;
        std::vector<NoisyGalaxy> out;
        for (int k = 0; k < count; ++k) {
            RandomStream r(2025, std::uint64_t(k), "galaxy");
            const int n_true = k % 9;
            const double beta = r.uniform(1.2, 1.6) * std::sqrt(n_true + 1.0);
            const double x = centre_of(side) + r.uniform(-0.5, 0.5);
            const double y = centre_of(side) + r.uniform(-0.5, 0.5);
            const double snr = 20.0 * std::pow(15.0, r.uniform());
            out.push_back(noisy_galaxy(centred_model(n_true, beta, x, y, 300 + unsigned(k)),
                                       side, snr, 13, std::uint64_t(k)));
        }
        return out;
    }();
    return set;
}

void BM_DecomposeTolerance(benchmark::State& state) {
    const std::vector<NoisyGalaxy>& set = tolerance_galaxies();
    DecomposeOptions options;
    options.beta_tolerance = std::pow(10.0, -double(state.range(0)));
    options.chi2_sigmas = double(state.range(1));
    std::vector<Decomposition> results(set.size());
    try {
        for (auto _ : state) {
            for (std::size_t k = 0; k < set.size(); ++k) {
                const NoisyGalaxy& g = set[k];
                const double beta = g.truth.beta_pix * 0.8;  // like a detection's a
                results[k] = decompose(g.image, g.weight, nullptr, g.truth.x + 0.3,
                                       g.truth.y - 0.2, beta, options);
            }
            benchmark::DoNotOptimize(results.data());
        }
    } catch (const std::exception& e) {
        state.SkipWithError(e.what());
        return;
    }
    double chi2r = 0.0, flux_err = 0.0, n_err = 0.0, fits = 0.0, converged = 0.0;
    for (std::size_t k = 0; k < set.size(); ++k) {
        const Decomposition& d = results[k];
        chi2r += d.chi2r;
        flux_err += relative_flux_error(d.fit.model, set[k].truth);
        n_err += std::abs(d.fit.model.n_max - set[k].truth.n_max);
        fits += double(d.fits);
        converged += d.converged ? 1.0 : 0.0;
    }
    const double n = double(set.size());
    state.counters["chi2r_mean"] = chi2r / n;
    state.counters["flux_err_rel"] = flux_err / n;
    state.counters["n_max_abs_err"] = n_err / n;
    state.counters["fits_mean"] = fits / n;
    state.counters["converged_frac"] = converged / n;
}
BENCHMARK(BM_DecomposeTolerance)->ArgsProduct({{1, 2, 3, 4}, {0, 2, 5}})
    ->ArgNames({"neg_log10_tol", "chi2_sigmas"})->Unit(benchmark::kMillisecond)
    ->MinTime(0.2);

// ---------------------------------------------------------------------------------------------
// Every stamp of the HDF-N cut.

struct HdfStamps {
    std::vector<Stamp> stamps;
    std::vector<MaskArray> masks;
    std::vector<double> x, y, beta;  // start centre (stamp FITS pixels) and β
    double noise_correlation = 1.0;
};

const HdfStamps& hdf_stamps() {
    static const HdfStamps data = [] {
        HdfStamps d;
        const ImageArray image = read_fits_image(kHdfImage);
        const ImageArray inverse_variance =
            inverse_variance_from(read_fits_image(kHdfWeight), NoiseMapType::weight, kHdfWeight);
        const DetectionResult field = detect_sources(image, &inverse_variance, DetectionOptions{});
        d.noise_correlation = field.noise_correlation;
        const StampOptions options;
        for (const Detection& object : field.objects) {
            CutStamp cut = cut_stamp(field, object, std::to_string(object.label), options);
            d.masks.push_back((cut.stamp.mask != 0.0).cast<std::uint8_t>());
            d.x.push_back(object.x - (cut.stamp.x0 - 1));
            d.y.push_back(object.y - (cut.stamp.y0 - 1));
            d.beta.push_back(std::max(object.a, 0.5));
            d.stamps.push_back(std::move(cut.stamp));
        }
        return d;
    }();
    return data;
}

void BM_DecomposeHdf(benchmark::State& state) {
    const HdfStamps* data = nullptr;
    try {
        data = &hdf_stamps();
    } catch (const std::exception& e) {
        state.SkipWithError(e.what());
        return;
    }
    DecomposeOptions options;
    options.noise_correlation = std::max(1.0, data->noise_correlation);
    const std::size_t count = data->stamps.size();
    std::vector<std::unique_ptr<Decomposition>> results(count);
    for (auto _ : state) {
        for (std::size_t k = 0; k < count; ++k) {
            const Stamp& s = data->stamps[k];
            try {
                results[k] = std::make_unique<Decomposition>(decompose(
                    s.image, s.weight, &data->masks[k], data->x[k], data->y[k], data->beta[k],
                    options));
            } catch (const Error&) {
                results[k].reset();  // a stamp no fit can use: the program warns and skips it
            }
        }
        benchmark::DoNotOptimize(results.data());
    }
    std::vector<double> n_max;
    double converged = 0.0, fits = 0.0;
    for (const auto& d : results) {
        if (!d) continue;
        n_max.push_back(d->fit.model.n_max);
        converged += d->converged ? 1.0 : 0.0;
        fits += double(d->fits);
    }
    const double fitted = double(n_max.size());
    state.counters["objects"] = double(count);
    state.counters["fitted"] = fitted;
    state.counters["converged_frac"] = fitted > 0 ? converged / fitted : nan;
    state.counters["fits_mean"] = fitted > 0 ? fits / fitted : nan;
    if (!n_max.empty()) {
        const auto mid = n_max.begin() + std::ptrdiff_t(n_max.size() / 2);
        std::nth_element(n_max.begin(), mid, n_max.end());
        state.counters["median_n_max"] = *mid;
    }
    // Printed with SI prefixes: "4.5ms" is 4.5 ms per stamp.
    state.counters["time_per_object"] = benchmark::Counter(
        double(count),
        benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
// ~1.3 s per pass over the ~290 stamps: two passes.
BENCHMARK(BM_DecomposeHdf)->Iterations(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
