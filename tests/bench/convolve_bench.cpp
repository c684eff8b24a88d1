// Exact shapelet convolution: run time and the error it buys (DESIGN §1, STYLE "Tests").
// Cases (n_gal, n_psf) = (4,4), (8,8), (15,8), (30,8). Counters:
//   error      max |Σ_l C_nml B_l(x;γ) − ∫ B_n B_m| over sample points (1D tensor), or
//              max |h − brute| / max |h| against a lattice-sum convolution of the point-sampled
//              models (2D), both computed once outside the timed loop;
//   ref_error  max over convolved.jsonl of max|Δa| / max|a| (README tolerance 1e-10).
#include "shapesim/convolve.hpp"

#include "shapesim/basis1d.hpp"
#include "shapesim/polar.hpp"

#include <benchmark/benchmark.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <string>
#include <vector>

using namespace shapesim;

namespace {

// Scales chosen like real fits: the galaxy basis resolves ≥ 1 px, the PSF β ~ 1.5 px.
constexpr double kPsfBeta = 1.5;
double galaxy_beta(int n_max) { return std::max(1.2, 0.5 * std::sqrt(n_max + 1.0)); }

ShapeletModel random_model(int n_max, double beta, unsigned seed) {
    std::mt19937_64 engine(seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    ShapeletModel m(50.0 + u(engine), 60.0 + u(engine), beta, n_max);
    for (const auto& [n, mm] : polar_indices(n_max)) {
        const double scale = 0.35 * std::exp(-n / 5.0);
        m.at(n, mm) = Complex(scale * u(engine), mm == 0 ? 0.0 : scale * u(engine));
    }
    m.at(0, 0) = 1.0;
    return m;
}

// 1D check of the tensor: trapezoid sum of B_n(x′; α) B_m(x − x′; b) at a few x.
double tensor_error(const ConvolutionTensor& c) {
    const double step = 0.02, half = 12.0 * std::max(c.alpha(), c.b()) * 1.5;
    std::vector<double> fa(c.n_f() + 1), gb(c.n_g() + 1), hl(c.n_out() + 1);
    double worst = 0.0;
    for (const double x : {-1.7, 0.3, 2.9}) {
        Eigen::MatrixXd brute = Eigen::MatrixXd::Zero(c.n_f() + 1, c.n_g() + 1);
        for (double xp = -half; xp <= half; xp += step) {
            hermite_functions(xp / c.alpha(), c.n_f(), fa.data());
            hermite_functions((x - xp) / c.b(), c.n_g(), gb.data());
            for (int n = 0; n <= c.n_f(); ++n)
                for (int m = 0; m <= c.n_g(); ++m)
                    brute(n, m) += step * fa[n] * gb[m] / std::sqrt(c.alpha() * c.b());
        }
        hermite_functions(x / c.gamma(), c.n_out(), hl.data());
        for (int n = 0; n <= c.n_f(); ++n)
            for (int m = 0; m <= c.n_g(); ++m) {
                double series = 0.0;
                for (int l = 0; l <= c.n_out(); ++l)
                    series += c(n, m, l) * hl[l] / std::sqrt(c.gamma());
                worst = std::max(worst, std::abs(series - brute(n, m)));
            }
    }
    return worst;
}

// 2D check: lattice sum δ² Σ f(x_i) g(x − x_i) of the point-sampled polar models (evaluate).
double brute_force_error(const ShapeletModel& f, const ShapeletModel& g, const ShapeletModel& h) {
    const double step = 0.25;
    const int rf = int(f.beta_pix * (std::sqrt(2.0 * f.n_max + 1) + 9) / step);
    const int rg = int(g.beta_pix * (std::sqrt(2.0 * g.n_max + 1) + 9) / step);
    Eigen::MatrixXd fs(2 * rf + 1, 2 * rf + 1), gs(2 * rg + 1, 2 * rg + 1);
    for (int i = -rf; i <= rf; ++i)
        for (int j = -rf; j <= rf; ++j)
            fs(i + rf, j + rf) = evaluate(f, f.x + i * step, f.y + j * step);
    for (int i = -rg; i <= rg; ++i)
        for (int j = -rg; j <= rg; ++j)
            gs(i + rg, j + rg) = evaluate(g, g.x + i * step, g.y + j * step);
    double worst = 0.0, peak = 0.0;
    for (int p = -20; p <= 20; p += 5)
        for (int q = -20; q <= 20; q += 5) {
            double sum = 0.0;
            for (int i = std::max(-rf, p - rg); i <= std::min(rf, p + rg); ++i)
                for (int j = std::max(-rf, q - rg); j <= std::min(rf, q + rg); ++j)
                    sum += fs(i + rf, j + rf) * gs(p - i + rg, q - j + rg);
            const double value = evaluate(h, h.x + p * step, h.y + q * step);
            worst = std::max(worst, std::abs(value - sum * step * step));
            peak = std::max(peak, std::abs(value));
        }
    return worst / peak;
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

// The 8 GalSim reference pairs of convolved.jsonl (found like the unit tests find them).
std::string reference_dir() {
    namespace fs = std::filesystem;
    const fs::path repo = fs::path(__FILE__).parent_path().parent_path().parent_path();
    std::vector<fs::path> candidates{repo / "tests/data/reference"};
    if (const char* env = std::getenv("SHAPESIM_DATA"))
        candidates.push_back(fs::path(env) / "reference");
    candidates.push_back("/work/shared/data/reference");
    candidates.push_back(repo / "../shared/data/reference");
    for (const auto& dir : candidates)
        if (fs::exists(dir / "convolved.jsonl")) return dir.string();
    return {};
}

ShapeletModel model_from_record(const nlohmann::json& j) {
    ShapeletModel m(j.at("x").get<double>(), j.at("y").get<double>(),
                    j.at("beta").get<double>() / j.at("pixel_scale").get<double>(),
                    j.at("n_max").get<int>());
    int k = 0;
    for (const auto& c : j.at("coeffs"))
        m.coeffs.at(k++) = Complex(c.at(0).get<double>(), c.at(1).get<double>());
    return m;
}

void BM_ConvolveReference(benchmark::State& state) {
    const std::string dir = reference_dir();
    if (dir.empty()) {
        state.SkipWithError("reference fixtures not found");
        return;
    }
    std::map<std::string, ShapeletModel> galaxies;
    std::ifstream models(dir + "/models.jsonl");
    for (std::string line; std::getline(models, line);) {
        const auto j = nlohmann::json::parse(line);
        galaxies[j.at("id").get<std::string>()] = model_from_record(j);
    }
    std::vector<ShapeletModel> gal, psf, result;
    std::ifstream in(dir + "/convolved.jsonl");
    for (std::string line; std::getline(in, line);) {
        const auto j = nlohmann::json::parse(line);
        gal.push_back(galaxies.at(j.at("galaxy_id").get<std::string>()));
        psf.push_back(model_from_record(j.at("psf")));
        result.push_back(model_from_record(j.at("result")));
    }
    for (auto _ : state)
        for (size_t i = 0; i < gal.size(); ++i)
            benchmark::DoNotOptimize(convolve(gal[i], psf[i]).coeffs.data());
    double worst = 0.0;
    for (size_t i = 0; i < gal.size(); ++i) {
        const Eigen::VectorXd a = real_parameters(result[i]);
        const Eigen::VectorXd d = real_parameters(convolve(gal[i], psf[i])) - a;
        worst = std::max(worst, d.cwiseAbs().maxCoeff() / a.cwiseAbs().maxCoeff());
    }
    state.counters["ref_error"] = worst;
    state.counters["pairs"] = double(gal.size());
}
BENCHMARK(BM_ConvolveReference)->Unit(benchmark::kMicrosecond);

}  // namespace
