// Exact shapelet convolution (share/shapesim/convolve.hpp) against GalSim's exact reference
// series and images, closed forms (two Gaussians), brute-force numerical convolution of the
// point-sampled models, flux, and the least-squares inverses (deconvolution, difference kernel).
// The fixtures are read here with nlohmann_json and cfitsio directly.
#include "shapesim/convolve.hpp"

#include "shapesim/basis1d.hpp"
#include "shapesim/error.hpp"
#include "shapesim/polar.hpp"
#include "shapesim/render.hpp"

#include <fitsio.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

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

constexpr double kPi = 3.14159265358979323846;

// Fixtures: <repo>/tests/data/reference (from __FILE__), then $SHAPESIM_DATA/reference, then
// /work/shared/data/reference, then <repo>/../shared/data/reference (CI's layout).
std::string convolve_reference_dir() {
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

// A shapesim.shapelet/1 record as a model in pixel units (beta_pix = beta / pixel_scale).
ShapeletModel model_from_record(const nlohmann::json& j) {
    ShapeletModel m(j.at("x").get<double>(), j.at("y").get<double>(),
                    j.at("beta").get<double>() / j.at("pixel_scale").get<double>(),
                    j.at("n_max").get<int>());
    int k = 0;
    for (const auto& c : j.at("coeffs"))
        m.coeffs.at(k++) = Complex(c.at(0).get<double>(), c.at(1).get<double>());
    EXPECT_EQ(k, polar_count(m.n_max));
    return m;
}

// An image HDU by EXTNAME (cfitsio's `file[EXTNAME]` syntax), rows along y.
ImageArray read_fits_extension(const std::string& path, const std::string& extname) {
    fitsfile* f = nullptr;
    int status = 0;
    long naxes[2] = {0, 0}, first[2] = {1, 1};
    fits_open_file(&f, (path + "[" + extname + "]").c_str(), READONLY, &status);
    fits_get_img_size(f, 2, naxes, &status);
    ImageArray image(naxes[1], naxes[0]);
    fits_read_pix(f, TDOUBLE, first, naxes[0] * naxes[1], nullptr, image.data(), nullptr,
                  &status);
    int close_status = 0;
    if (f) fits_close_file(f, &close_status);
    EXPECT_EQ(status, 0) << path << "[" << extname << "]";
    return image;
}

struct ReferenceLine {
    std::string hdu;
    ShapeletModel galaxy, psf, result;
    int nx = 0, ny = 0;
    double flux = 0.0;
};

// The 8 lines of convolved.jsonl with their galaxies from models.jsonl.
std::vector<ReferenceLine> read_reference_lines(const std::string& dir) {
    std::map<std::string, ShapeletModel> galaxies;
    std::ifstream models(dir + "/models.jsonl");
    for (std::string line; std::getline(models, line);) {
        const auto j = nlohmann::json::parse(line);
        galaxies[j.at("id").get<std::string>()] = model_from_record(j);
    }
    std::vector<ReferenceLine> out;
    std::ifstream in(dir + "/convolved.jsonl");
    for (std::string line; std::getline(in, line);) {
        const auto j = nlohmann::json::parse(line);
        ReferenceLine r;
        r.hdu = j.at("hdu").get<std::string>();
        r.galaxy = galaxies.at(j.at("galaxy_id").get<std::string>());
        r.galaxy.x = j.at("x").get<double>();  // the convolved stamp's centre (README)
        r.galaxy.y = j.at("y").get<double>();
        r.psf = model_from_record(j.at("psf"));
        r.result = model_from_record(j.at("result"));
        r.nx = j.at("nx").get<int>();
        r.ny = j.at("ny").get<int>();
        r.flux = j.at("flux").get<double>();
        out.push_back(std::move(r));
    }
    return out;
}

// F = 2√π β Σ_{n even} a_{n,0} (DESIGN §2) and its scale 2√π β Σ |a_{n,0}|.
double flux_of(const ShapeletModel& m, bool absolute = false) {
    double sum = 0.0;
    for (int n = 0; n <= m.n_max; n += 2) {
        const double a = m.at(n, 0).real();
        sum += absolute ? std::abs(a) : a;
    }
    return 2.0 * std::sqrt(kPi) * m.beta_pix * sum;
}

// max |Δ| over the real parameters, and max |a| of the reference.
double max_abs_difference(const ShapeletModel& a, const ShapeletModel& b) {
    return (real_parameters(a) - real_parameters(b)).cwiseAbs().maxCoeff();
}
double max_abs(const ShapeletModel& a) { return real_parameters(a).cwiseAbs().maxCoeff(); }

// A deterministic random model: galaxy-like (a_00 dominant, decaying with n) or fully random.
ShapeletModel random_model(int n_max, double beta, unsigned seed, bool galaxy = true) {
    std::mt19937_64 engine(seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    ShapeletModel m(10.0 + u(engine), 12.0 + u(engine), beta, n_max);
    for (const auto& [n, mm] : polar_indices(n_max)) {
        const double scale = galaxy ? 0.35 * std::exp(-n / 5.0) : 1.0;
        m.at(n, mm) = Complex(scale * u(engine), mm == 0 ? 0.0 : scale * u(engine));
    }
    if (galaxy) m.at(0, 0) = 1.0 + 0.2 * u(engine);
    return m;
}

}  // namespace

// C_000 of two Gaussians in closed form: B_0(α) ∗ B_0(b) = √(2π) π^{−1/4} √(αb/γ) B_0(γ).
TEST(Convolve, TensorOfTwoGaussiansIsClosedForm) {
    for (const auto& [alpha, b] : {std::pair{1.0, 1.0}, {2.7, 0.4}, {0.3, 5.0}}) {
        const ConvolutionTensor c(alpha, b, 3, 2);
        const double gamma = std::hypot(alpha, b);
        EXPECT_DOUBLE_EQ(c.gamma(), gamma);
        const double expected =
            std::sqrt(2.0 * kPi) * std::pow(kPi, -0.25) * std::sqrt(alpha * b / gamma);
        EXPECT_NEAR(c(0, 0, 0), expected, 1e-15 * expected);
        EXPECT_EQ(c(0, 0, 1), 0.0);  // parity
        EXPECT_EQ(c(1, 0, 3), 0.0);  // l > n + m
    }
}

// Σ_l C_nml B_l(x; γ) equals ∫ B_n(x′; α) B_m(x − x′; b) dx′ by the trapezoid rule on a fine
// grid (spectrally accurate for these entire, Gaussian-decaying integrands): 1e-13 absolute.
TEST(Convolve, TensorMatchesBruteForce1D) {
    const double alpha = 1.3, b = 0.8;
    const int n_f = 7, n_g = 5;
    const ConvolutionTensor c(alpha, b, n_f, n_g);
    const double step = 0.01, half_width = 25.0;
    const int points = int(2 * half_width / step) + 1;
    std::vector<double> fa(n_f + 1), gb(n_g + 1), hl(c.n_out() + 1);
    double worst = 0.0;
    for (const double x : {-2.3, -0.7, 0.0, 0.45, 1.9, 3.6}) {
        Eigen::MatrixXd brute = Eigen::MatrixXd::Zero(n_f + 1, n_g + 1);
        for (int p = 0; p < points; ++p) {
            const double xp = -half_width + p * step;
            hermite_functions(xp / alpha, n_f, fa.data());
            hermite_functions((x - xp) / b, n_g, gb.data());
            for (int n = 0; n <= n_f; ++n)
                for (int m = 0; m <= n_g; ++m)
                    brute(n, m) += step * fa[n] * gb[m] / std::sqrt(alpha * b);
        }
        hermite_functions(x / c.gamma(), c.n_out(), hl.data());
        for (int n = 0; n <= n_f; ++n)
            for (int m = 0; m <= n_g; ++m) {
                double series = 0.0;
                for (int l = 0; l <= c.n_out(); ++l)
                    series += c(n, m, l) * hl[l] / std::sqrt(c.gamma());
                worst = std::max(worst, std::abs(series - brute(n, m)));
            }
    }
    EXPECT_LT(worst, 1e-13);
}

// (a) The 8 exact `result` series of convolved.jsonl, coefficient by coefficient, to
// 1e-10 · max|a| (README's tolerance), and their scale γ; then the images of convolved.fits
// to 1e-9 of the peak (README; the DFT images themselves carry ~6e-13).
TEST(Convolve, ReproducesReferenceSeriesAndImages) {
    const std::string dir = convolve_reference_dir();
    if (dir.empty()) GTEST_SKIP() << "reference fixtures not found";
    const auto lines = read_reference_lines(dir);
    ASSERT_EQ(lines.size(), 8u);
    for (const auto& r : lines) {
        const ShapeletModel h = convolve(r.galaxy, r.psf);
        ASSERT_EQ(h.n_max, r.result.n_max) << r.hdu;
        EXPECT_NEAR(h.beta_pix, r.result.beta_pix, 1e-14 * h.beta_pix) << r.hdu;
        EXPECT_EQ(h.x, r.result.x);
        EXPECT_EQ(h.y, r.result.y);
        EXPECT_LE(max_abs_difference(h, r.result), 1e-10 * max_abs(r.result)) << r.hdu;
        EXPECT_NEAR(flux_of(h), r.flux, 1e-12 * flux_of(h, true)) << r.hdu;

        const ImageArray truth = read_fits_extension(dir + "/convolved.fits", r.hdu);
        ASSERT_EQ(truth.cols(), r.nx);
        ASSERT_EQ(truth.rows(), r.ny);
        const ImageArray image = render_stamp(h, r.nx, r.ny);
        const double peak = truth.abs().maxCoeff();
        EXPECT_LT((image - truth).abs().maxCoeff(), 1e-9 * peak) << r.hdu;
    }
}

// (b) Convolution equals brute-force numerical convolution of the point-sampled models
// (the paper's polar formula, `evaluate`) on a fine lattice of step δ: h(x) ≈ δ² Σ f g. The
// lattice sum of these entire functions converges spectrally (measured ≤ 4e-15 at this step);
// we ask 1e-8 of max|h|, the brief's tolerance.
TEST(Convolve, MatchesBruteForceConvolution2D) {
    struct Case {
        int n_f, n_g;
        double alpha, b;
        unsigned seed;
        bool galaxy;
    };
    for (const Case& k : {Case{8, 5, 2.2, 1.4, 11, true}, Case{6, 4, 1.1, 1.7, 12, false},
                          Case{3, 8, 2.6, 1.2, 13, true}}) {
        const ShapeletModel f = random_model(k.n_f, k.alpha, k.seed, k.galaxy);
        ShapeletModel g = random_model(k.n_g, k.b, k.seed + 100, true);
        g.x = 1e3;  // the PSF's own position plays no part
        const ShapeletModel h = convolve(f, g);
        const double step = 0.25;  // ≥ 4 samples per β: the lattice sum reaches ~5e-15
        const int rf = int(k.alpha * (std::sqrt(2.0 * k.n_f + 1) + 9) / step);
        const int rg = int(k.b * (std::sqrt(2.0 * k.n_g + 1) + 9) / step);
        Eigen::MatrixXd fs(2 * rf + 1, 2 * rf + 1), gs(2 * rg + 1, 2 * rg + 1);
        for (int i = -rf; i <= rf; ++i)
            for (int j = -rf; j <= rf; ++j)
                fs(i + rf, j + rf) = evaluate(f, f.x + i * step, f.y + j * step);
        for (int i = -rg; i <= rg; ++i)
            for (int j = -rg; j <= rg; ++j)
                gs(i + rg, j + rg) = evaluate(g, g.x + i * step, g.y + j * step);
        double worst = 0.0, peak = 0.0;
        for (int p = -24; p <= 24; p += 3)
            for (int q = -21; q <= 21; q += 3) {  // points (p, q) lattice steps off the centre
                double sum = 0.0;
                for (int i = std::max(-rf, p - rg); i <= std::min(rf, p + rg); ++i)
                    for (int j = std::max(-rf, q - rg); j <= std::min(rf, q + rg); ++j)
                        sum += fs(i + rf, j + rf) * gs(p - i + rg, q - j + rg);
                sum *= step * step;
                const double value = evaluate(h, h.x + p * step, h.y + q * step);
                worst = std::max(worst, std::abs(value - sum));
                peak = std::max(peak, std::abs(value));
            }
        EXPECT_LT(worst, 1e-8 * peak) << "n_f " << k.n_f << " n_g " << k.n_g;
    }
}

// (c) flux_h = flux_f · flux_g exactly (to 1e-12 of the flux scale 2√π γ Σ|a_{n,0}|), with no
// implicit normalisation of the PSF.
TEST(Convolve, FluxMultiplies) {
    for (unsigned seed = 1; seed <= 6; ++seed) {
        const ShapeletModel f = random_model(2 * seed + 1, 0.8 + 0.5 * seed, seed, seed % 2);
        const ShapeletModel g = random_model(seed + 2, 2.1 - 0.2 * seed, seed + 50, true);
        const ShapeletModel h = convolve(f, g);
        EXPECT_NEAR(flux_of(h), flux_of(f) * flux_of(g), 1e-12 * flux_of(h, true));
    }
}

// Conventions: the result sits at the galaxy's centre, with β = γ and n_max N_f + N_g; the
// PSF's position is ignored; f ∗ g = g ∗ f coefficient by coefficient.
TEST(Convolve, ConventionsAndCommutation) {
    const ShapeletModel f = random_model(7, 2.0, 21);
    ShapeletModel g = random_model(4, 1.2, 22);
    const ShapeletModel h = convolve(f, g);
    EXPECT_EQ(h.x, f.x);
    EXPECT_EQ(h.y, f.y);
    EXPECT_EQ(h.n_max, 11);
    EXPECT_DOUBLE_EQ(h.beta_pix, std::hypot(2.0, 1.2));
    g.x += 17.5;
    g.y -= 3.25;
    EXPECT_EQ(real_parameters(convolve(f, g)), real_parameters(h));
    const ShapeletModel swapped = convolve(g, f);
    EXPECT_LT(max_abs_difference(swapped, h), 1e-14 * max_abs(h));
}

// The linear maps reproduce `convolve` (for fitting PSF-convolved models).
TEST(Convolve, LinearMapsMatchConvolve) {
    const ShapeletModel g = random_model(6, 1.5, 31);
    for (const int n_f : {0, 3, 10}) {
        const ShapeletModel f = random_model(n_f, 2.4, 30 + n_f, false);
        const ShapeletModel h = convolve(f, g);
        const Eigen::MatrixXd m = convolution_matrix(g, f.beta_pix, n_f);
        ASSERT_EQ(m.rows(), real_count(n_f + 6));
        ASSERT_EQ(m.cols(), real_count(n_f));
        const Eigen::VectorXd mapped = m * real_parameters(f);
        EXPECT_LT((mapped - real_parameters(h)).cwiseAbs().maxCoeff(), 1e-13 * max_abs(h));
        const Eigen::MatrixXd l = cartesian_convolution_matrix(to_cartesian(g), f.beta_pix, n_f);
        const Eigen::VectorXd packed = l * pack_cartesian(to_cartesian(f).b, n_f);
        EXPECT_LT((packed - pack_cartesian(to_cartesian(h).b, h.n_max)).cwiseAbs().maxCoeff(),
                  1e-13 * max_abs(h));
    }
}

// (d) Deconvolution inverts convolution where well posed (γ > b; noise-free h = g ∗ f with
// n_max(f) ≤ n_max_out) to 1e-10 · max|a|; asking a higher n_max_out gives zeros above.
// Condition numbers of these maps are ≤ ~1e3 (rounding × κ ≪ 1e-10).
TEST(Convolve, DeconvolutionInvertsConvolution) {
    struct Case {
        int n_f, n_g;
        double alpha, b;
    };
    for (const Case& k : {Case{4, 4, 2.0, 1.5}, Case{8, 6, 3.0, 1.3}, Case{12, 8, 2.5, 1.2},
                          Case{0, 5, 1.0, 1.6}}) {
        const ShapeletModel f = random_model(k.n_f, k.alpha, 40 + k.n_f, false);
        const ShapeletModel g = random_model(k.n_g, k.b, 41 + k.n_g, true);
        const ShapeletModel h = convolve(f, g);
        InverseReport report;
        const ShapeletModel back = deconvolve(h, g, k.n_f + 2, &report);
        EXPECT_NEAR(back.beta_pix, k.alpha, 1e-14 * k.alpha);
        EXPECT_EQ(back.x, h.x);
        EXPECT_LT(max_abs_difference(back, with_n_max(f, k.n_f + 2)), 1e-10 * max_abs(f))
            << "n_f " << k.n_f << " cond " << report.condition_number;
        EXPECT_LT(report.relative_residual, 1e-12);
        EXPECT_LT(report.condition_number, 1e4);
    }
}

TEST(Convolve, DeconvolutionRejectsIllPosedInput) {
    const ShapeletModel g = random_model(3, 1.5, 51);
    const ShapeletModel narrow = random_model(3, 1.5, 52);
    EXPECT_THROW(deconvolve(narrow, g, 3), Error);  // γ = b: nothing left to deconvolve
    ShapeletModel zero_psf(0, 0, 1.0, 2);
    EXPECT_THROW(deconvolve(random_model(3, 2.0, 53), zero_psf, 3), Error);
}

// (e) The difference kernel between Gaussians is the exact Gaussian: new = N(b_new) with flux
// F_new, old = N(b_old) with flux F_old ⇒ k = Gaussian of scale √(b_new² − b_old²) and flux
// F_new / F_old; all higher coefficients vanish and the residual is zero.
TEST(Convolve, DifferenceKernelOfGaussiansIsGaussian) {
    const double b_old = 1.2, b_new = 2.0, flux_old = 0.9, flux_new = 1.1;
    ShapeletModel old_psf(3.0, 4.0, b_old, 0), new_psf(5.0, 6.0, b_new, 0);
    old_psf.at(0, 0) = flux_old / (2.0 * std::sqrt(kPi) * b_old);
    new_psf.at(0, 0) = flux_new / (2.0 * std::sqrt(kPi) * b_new);
    const DifferenceKernel d = difference_kernel(old_psf, new_psf, 6);
    const double beta_k = std::sqrt(b_new * b_new - b_old * b_old);
    EXPECT_NEAR(d.kernel.beta_pix, beta_k, 1e-15 * beta_k);
    EXPECT_EQ(d.kernel.x, new_psf.x);
    ShapeletModel exact(new_psf.x, new_psf.y, beta_k, 6);
    exact.at(0, 0) = flux_new / flux_old / (2.0 * std::sqrt(kPi) * beta_k);
    EXPECT_LT(max_abs_difference(d.kernel, exact), 1e-13 * max_abs(exact));
    EXPECT_LT(d.report.relative_residual, 1e-13);
}

// A general difference kernel: new = k ∗ old is recovered exactly; a new PSF that no kernel of
// the order reaches (narrower along one axis than the old one) is flagged by the residual.
TEST(Convolve, DifferenceKernelRecoversKernelAndFlagsResidual) {
    const ShapeletModel old_psf = random_model(6, 1.3, 61);
    const ShapeletModel k_true = random_model(4, 1.1, 62);
    ShapeletModel new_psf = convolve(k_true, old_psf);
    const DifferenceKernel d = difference_kernel(old_psf, new_psf, 4);
    EXPECT_LT(max_abs_difference(d.kernel, k_true), 1e-10 * max_abs(k_true));
    EXPECT_LT(d.report.relative_residual, 1e-12);

    ShapeletModel unreachable = random_model(8, 1.8, 63, false);
    const DifferenceKernel bad = difference_kernel(old_psf, unreachable, 4);
    EXPECT_GT(bad.report.relative_residual, 1e-3);
    EXPECT_THROW(difference_kernel(new_psf, old_psf, 4), Error);
}
