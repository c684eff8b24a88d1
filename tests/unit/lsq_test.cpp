// Weighted least-squares decomposition: exact recovery, honest errors, bad input.
#include "shapesim/lsq.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/convolve.hpp"
#include "shapesim/error.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/polar.hpp"
#include "shapesim/render.hpp"
#include "shapesim/rng.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <random>

using namespace shapesim;

namespace {
double max_relative_error(const ShapeletModel& fit, const ShapeletModel& truth) {
    const Eigen::VectorXd a = real_parameters(fit), b = real_parameters(truth);
    return (a - b).cwiseAbs().maxCoeff() / b.cwiseAbs().maxCoeff();
}

// The rms of pull(image, weight, d) over `draws` images: `clean` plus Gaussian noise of σ
// (std::mt19937_64 seeded with `seed`), weights 1/σ².
template <class Pull>
double pull_rms(const ImageArray& clean, double sigma, unsigned seed, int draws, const Pull& pull) {
    const ImageArray weight = ImageArray::Constant(clean.rows(), clean.cols(), 1.0 / (sigma * sigma));
    std::mt19937_64 engine(seed);
    std::normal_distribution<double> normal(0.0, sigma);
    double sum2 = 0.0;
    for (int d = 0; d < draws; ++d) {
        ImageArray image = clean;
        for (Eigen::Index k = 0; k < image.size(); ++k) image.data()[k] += normal(engine);
        const double p = pull(image, weight, d);
        sum2 += p * p;
    }
    return std::sqrt(sum2 / draws);
}
}  // namespace

// Noise-free fits of the 24 GalSim stamps at their own centre and β recover the stored
// coefficients to 1e-10 (README suggests 1e-8; GalSim's own fit reached 2.6e-15).
TEST(Lsq, RecoversReferenceCoefficients) {
    for (const auto& r : test::reference_models()) {
        const ImageArray weight = ImageArray::Ones(r.ny, r.nx);
        const ShapeletFit fit = fit_shapelets(r.stamp, weight, nullptr, r.model.x, r.model.y,
                                              r.model.beta_pix, r.model.n_max);
        EXPECT_LT(max_relative_error(fit.model, r.model), 1e-10) << r.id;
        EXPECT_LT(fit.residual.abs().maxCoeff(), 1e-10 * r.stamp.abs().maxCoeff()) << r.id;
    }
}

// Masked, NaN and zero-weight pixels are left out, and the rest still determine the model.
TEST(Lsq, ExcludedPixelsAreIgnored) {
    const ShapeletModel truth = test::random_model(6, 2.0, 16.3, 15.8, 11);
    ImageArray image = render_stamp(truth, 32, 32);
    ImageArray weight = ImageArray::Ones(32, 32);
    MaskArray mask = MaskArray::Zero(32, 32);
    mask.block(2, 20, 8, 8).setOnes();
    image.block(2, 20, 8, 8).setConstant(1e6);  // a "neighbour" that must not leak in
    image(30, 1) = std::nan("");
    weight(5, 5) = 0.0;
    image(5, 5) = -1e9;
    const ShapeletFit fit = fit_shapelets(image, weight, &mask, truth.x, truth.y, 2.0, 6);
    EXPECT_LT(max_relative_error(fit.model, truth), 1e-10);
    EXPECT_EQ(fit.pixels_used, 32 * 32 - 64 - 2);
    EXPECT_TRUE(std::isnan(fit.residual(30, 1)));
}

// With Gaussian noise of known σ, the coefficient pulls (â − a)/σ_a have mean 0 and width 1
// within 5% and χ²_r averages 1: the covariance is right. 400 realisations × 28 parameters.
TEST(Lsq, PullsAreUnitNormal) {
    const int n_max = 6, size = 24, trials = 400;
    const ShapeletModel truth = test::random_model(n_max, 2.2, 12.4, 12.7, 21);
    const ImageArray clean = render_stamp(truth, size, size);
    const double sigma = 0.01 * clean.abs().maxCoeff();
    const ImageArray weight = ImageArray::Constant(size, size, 1.0 / (sigma * sigma));
    std::mt19937_64 engine(12345);
    std::normal_distribution<double> normal;
    const Eigen::VectorXd true_params = real_parameters(truth);
    double sum = 0.0, sum2 = 0.0, chi2r_sum = 0.0;
    long count = 0;
    for (int t = 0; t < trials; ++t) {
        ImageArray noisy = clean;
        for (long p = 0; p < noisy.size(); ++p) noisy.data()[p] += sigma * normal(engine);
        const ShapeletFit fit = fit_shapelets(noisy, weight, nullptr, truth.x, truth.y, 2.2, n_max);
        const Eigen::VectorXd pull =
            (real_parameters(fit.model) - true_params).cwiseQuotient(fit.errors());
        sum += pull.sum();
        sum2 += pull.squaredNorm();
        count += pull.size();
        chi2r_sum += fit.chi2r;
    }
    const double mean = sum / count, width = std::sqrt(sum2 / count - mean * mean);
    EXPECT_LT(std::abs(mean), 0.05);
    EXPECT_NEAR(width, 1.0, 0.05);
    // χ²_r of dof ≈ 548 has sd √(2/548) = 0.06 per fit, 0.003 over 400: 1% is > 3σ.
    EXPECT_NEAR(chi2r_sum / trials, 1.0, 0.01);
}

// The separable normal-equation path and the QR path agree, on every reference stamp.
TEST(Lsq, NormalAndQrSolversAgree) {
    for (const auto& r : test::reference_models()) {
        const ImageArray weight = ImageArray::Ones(r.ny, r.nx);
        const auto fit = [&](LsqSolver solver) {
            return fit_shapelets(r.stamp, weight, nullptr, r.model.x, r.model.y, r.model.beta_pix,
                                 r.model.n_max, solver);
        };
        const ShapeletFit normal = fit(LsqSolver::normal), qr = fit(LsqSolver::qr);
        EXPECT_EQ(fit(LsqSolver::automatic).solver_used, LsqSolver::normal) << r.id;
        EXPECT_LT(max_relative_error(normal.model, qr.model), 1e-11) << r.id;
        EXPECT_LT((normal.covariance - qr.covariance).cwiseAbs().maxCoeff(),
                  1e-10 * qr.covariance.cwiseAbs().maxCoeff()) << r.id;
    }
}

// A basis much finer than the pixels is ill-conditioned: the automatic choice falls back to
// QR, which still fits the (noise-free) data.
TEST(Lsq, IllConditionedFallsBackToQr) {
    const ShapeletModel truth = test::random_model(8, 0.45, 10.2, 9.9, 4);
    const ImageArray image = render_stamp(truth, 20, 20);
    const ShapeletFit fit =
        fit_shapelets(image, ImageArray::Ones(20, 20), nullptr, truth.x, truth.y, 0.45, 8);
    EXPECT_EQ(fit.solver_used, LsqSolver::qr);
    EXPECT_LT(fit.residual.abs().maxCoeff(), 1e-9 * image.abs().maxCoeff());
}

TEST(Lsq, BadInputIsAnError) {
    const ImageArray image = ImageArray::Ones(10, 10);
    const ImageArray weight = ImageArray::Ones(10, 10);
    EXPECT_THROW(fit_shapelets(image, ImageArray::Ones(10, 9), nullptr, 5, 5, 1.0, 2), Error);
    ImageArray negative = weight;
    negative(3, 3) = -1.0;
    EXPECT_THROW(fit_shapelets(image, negative, nullptr, 5, 5, 1.0, 2), Error);
    EXPECT_THROW(fit_shapelets(image, weight, nullptr, 5, 5, 0.0, 2), Error);
    EXPECT_THROW(fit_shapelets(image, weight, nullptr, 5, 5, 1.0, 20), Error);  // 231 > 100 px
    EXPECT_THROW(fit_shapelets(image, ImageArray::Zero(10, 10), nullptr, 5, 5, 1.0, 1), Error);
    try {
        fit_shapelets(image, negative, nullptr, 5, 5, 1.0, 2);
    } catch (const Error& e) {
        EXPECT_EQ(e.field(), "weight");
        EXPECT_NE(std::string(e.what()).find("4,4"), std::string::npos) << e.what();
    }
}

// Forward modelling: GalSim's exact PSF-convolved stamps, fitted through their PSF at the
// galaxy's own β and order, give back the intrinsic galaxy (the unknowns are its coefficients,
// the design the convolved basis), to 1e-8 of its largest coefficient.
TEST(LsqConvolved, RecoversTheIntrinsicGalaxyFromGalSimStamps) {
    const auto& cases = test::reference_convolutions();
    ASSERT_FALSE(cases.empty());
    double worst = 0.0;
    for (const auto& c : cases) {
        const ImageArray weight = ImageArray::Ones(c.image.rows(), c.image.cols());
        const ShapeletFit fit =
            fit_convolved_shapelets(c.image, weight, nullptr, c.result.x, c.result.y,
                                    c.galaxy.beta_pix, c.galaxy.n_max, to_cartesian(c.psf));
        const double error = max_relative_error(fit.model, c.galaxy);
        worst = std::max(worst, error);
        EXPECT_LT(error, 1e-8) << c.record.hdu;
        EXPECT_EQ(fit.model.n_max, c.galaxy.n_max);
        EXPECT_LT(fit.residual.abs().maxCoeff(), 1e-8 * c.image.abs().maxCoeff()) << c.record.hdu;
    }
    std::cout << "  [measured] worst relative coefficient error " << worst << "\n";
}

// With noise, the intrinsic coefficients' errors are honest (pulls of the a_00 real part over
// 200 noise draws: rms ≈ 1), and the normal and QR solvers agree.
TEST(LsqConvolved, PullsAndSolversAgree) {
    const ShapeletModel galaxy = test::random_model(4, 2.0, 20.3, 19.8, 21, true, 0.3);
    ShapeletModel psf = test::random_model(4, 1.5, 0.0, 0.0, 22, true, 0.2);
    const double f = flux(psf);
    for (auto& c : psf.coeffs) c /= f;
    const CartesianModel psf_cart = to_cartesian(psf);
    const ImageArray clean = render_stamp(to_cartesian(convolve(galaxy, psf)), 40, 40);
    const double rms = pull_rms(clean, 0.02 * clean.maxCoeff(), 5, 200,
                                [&](const ImageArray& image, const ImageArray& weight, int d) {
        const ShapeletFit fit = fit_convolved_shapelets(image, weight, nullptr, galaxy.x, galaxy.y,
                                                        2.0, 4, psf_cart);
        if (d == 0) {
            const ShapeletFit qr = fit_convolved_shapelets(image, weight, nullptr, galaxy.x,
                                                           galaxy.y, 2.0, 4, psf_cart, LsqSolver::qr);
            EXPECT_LT(max_relative_error(qr.model, fit.model), 1e-9);
            EXPECT_NEAR(qr.chi2, fit.chi2, 1e-8 * fit.chi2);
            EXPECT_EQ(qr.solver_used, LsqSolver::qr);
        }
        return (real_parameters(fit.model)(0) - real_parameters(galaxy)(0)) /
               std::sqrt(fit.covariance(0, 0));
    });
    std::cout << "  [measured] a_00 pull rms " << rms << "\n";
    EXPECT_NEAR(rms, 1.0, 0.15);
}

// One fixed shape, its amplitude fitted (decompose's elliptical Gaussians): a noise-free image
// of 3.7 × the shape gives 3.7 back, plain and through a PSF, with a residual at rounding; the
// amplitude's error is σ/√(sᵀWs) (pull rms ≈ 1 over 300 noise draws).
TEST(LsqAmplitude, RecoversTheAmplitudeOfAFixedShape) {
    ShapeletModel shape = test::random_model(4, 2.2, 0.0, 0.0, 31, true, 0.3);
    shape.coeffs[0] = 1.0;
    ShapeletModel truth = shape;
    truth.x = 20.4;
    truth.y = 19.7;
    for (auto& c : truth.coeffs) c *= 3.7;
    const ImageArray ones = ImageArray::Ones(40, 40);
    const ImageArray plain = render_stamp(to_cartesian(truth), 40, 40);
    const ShapeletFit a = fit_shape_amplitude(plain, ones, nullptr, truth.x, truth.y, shape);
    EXPECT_NEAR(a.model.coeffs[0].real(), 3.7, 1e-10);
    EXPECT_LT(a.residual.abs().maxCoeff(), 1e-10 * plain.abs().maxCoeff());
    EXPECT_EQ(a.dof, 40 * 40 - 1);
    ShapeletModel psf = test::random_model(4, 1.5, 0.0, 0.0, 32, true, 0.2);
    const double f = flux(psf);
    for (auto& c : psf.coeffs) c /= f;
    const CartesianModel psf_cart = to_cartesian(psf);
    const ImageArray seen = render_stamp(to_cartesian(convolve(truth, psf)), 40, 40);
    const ShapeletFit b = fit_shape_amplitude(seen, ones, nullptr, truth.x, truth.y, shape, &psf_cart);
    EXPECT_NEAR(b.model.coeffs[0].real(), 3.7, 1e-9);
    EXPECT_LT(b.residual.abs().maxCoeff(), 1e-9 * seen.abs().maxCoeff());
    // Pulls of the amplitude.
    const double rms = pull_rms(plain, 0.05 * plain.maxCoeff(), 7, 300,
                                [&](const ImageArray& image, const ImageArray& weight, int) {
        const ShapeletFit fit = fit_shape_amplitude(image, weight, nullptr, truth.x, truth.y, shape);
        return (fit.model.coeffs[0].real() - 3.7) / std::sqrt(fit.covariance(0, 0));
    });
    std::cout << "  [measured] amplitude pull rms " << rms << "\n";
    EXPECT_NEAR(rms, 1.0, 0.12);
    EXPECT_THROW(fit_shape_amplitude(plain, ImageArray::Zero(40, 40), nullptr, 20.0, 20.0, shape), Error);
}

namespace {
// The correlation of white noise smoothed by [1, 2, 1] ⊗ [1, 2, 1] (ξ = k ⋆ k / Σk², radius 2;
// F² = (Σk)²/Σk² = 256/36), and the smoothing itself, for the noise take-up tests.
const double smoothing[3] = {1.0, 2.0, 1.0};
NoiseCorrelation smoothed_white_correlation() {
    NoiseCorrelation xi;
    xi.radius = 2;
    double auto1d[5] = {0, 0, 0, 0, 0};
    for (int d = -2; d <= 2; ++d)
        for (int a = 0; a < 3; ++a)
            if (a + d >= 0 && a + d < 3) auto1d[d + 2] += smoothing[a] * smoothing[a + d];
    for (int dy = -2; dy <= 2; ++dy)
        for (int dx = -2; dx <= 2; ++dx)
            xi.values.push_back(auto1d[dy + 2] * auto1d[dx + 2] / (auto1d[2] * auto1d[2]));
    return xi;
}

// T = tr((BᵀB)⁻¹BᵀRB) the long way: every column of the design rendered on its own (a unit
// Cartesian coefficient, through `psf` when given), R written out pixel by pixel.
double brute_force_take_up(const ImageArray& weight, const MaskArray& mask, double x, double y,
                           double beta, int n_max, const NoiseCorrelation& xi,
                           const CartesianModel* psf) {
    const int ny = int(weight.rows()), nx = int(weight.cols());
    std::vector<std::pair<int, int>> used;
    for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i)
            if (weight(j, i) > 0.0 && mask(j, i) == 0) used.push_back({j, i});
    const int p = real_count(n_max);
    Eigen::MatrixXd design(used.size(), p);
    int k = 0;
    for (int n = 0; n <= n_max; ++n)
        for (int n1 = 0; n1 <= n; ++n1, ++k) {
            CartesianModel unit(x, y, beta, n_max);
            unit.b(n1, n - n1) = 1.0;
            const ImageArray column = render_stamp(psf ? convolve(unit, *psf) : unit, nx, ny);
            for (std::size_t r = 0; r < used.size(); ++r)
                design(Eigen::Index(r), k) = std::sqrt(weight(used[r].first, used[r].second)) *
                                             column(used[r].first, used[r].second);
        }
    Eigen::MatrixXd correlation(used.size(), used.size());
    for (std::size_t a = 0; a < used.size(); ++a)
        for (std::size_t b = 0; b < used.size(); ++b)
            correlation(Eigen::Index(a), Eigen::Index(b)) =
                xi.at(used[b].second - used[a].second, used[b].first - used[a].first);
    const Eigen::MatrixXd normal = design.transpose() * design;
    return normal.ldlt().solve(design.transpose() * correlation * design).trace();
}
}  // namespace

// The exact noise take-up: p for white noise (with weights, a mask and through a PSF), the
// brute-force trace for correlated noise, and the mean χ² a fit leaves on 400 noise images.
TEST(LsqNoiseTakeUp, WhiteIsTheCountCorrelatedIsTheTrace) {
    const int side = 13;
    ImageArray weight(side, side);
    std::mt19937_64 engine(3);
    std::uniform_real_distribution<double> spread(0.5, 2.0);
    for (Eigen::Index k = 0; k < weight.size(); ++k) weight.data()[k] = spread(engine);
    MaskArray mask = MaskArray::Zero(side, side);
    mask.block(0, 9, 4, 4).setConstant(1);
    const ImageArray image = ImageArray::Zero(side, side);
    const NoiseCorrelation white{0, {1.0}};
    CartesianModel psf(0.0, 0.0, 1.2, 2);
    psf.b(0, 0) = 1.0 / std::sqrt(4.0 * pi);
    psf.b(2, 0) = psf.b(0, 2) = 0.05;
    for (const CartesianModel* through : std::vector<const CartesianModel*>{nullptr, &psf}) {
        EXPECT_NEAR(noise_take_up(image, weight, &mask, 6.7, 7.2, 1.8, 3, white, through),
                    real_count(3), 1e-9);
        const NoiseCorrelation xi = smoothed_white_correlation();
        const double fast = noise_take_up(image, weight, &mask, 6.7, 7.2, 1.8, 3, xi, through);
        const double brute = brute_force_take_up(weight, mask, 6.7, 7.2, 1.8, 3, xi, through);
        EXPECT_NEAR(fast, brute, 1e-9 * brute) << (through ? "through the PSF" : "plain");
    }
}

TEST(LsqNoiseTakeUp, IsTheMeanChi2AFitLeavesOnCorrelatedNoise) {
    const int side = 25, n_max = 4, trials = 400;
    const double beta = 2.5, centre = 13.0;
    const NoiseCorrelation xi = smoothed_white_correlation();
    const ImageArray weight = ImageArray::Ones(side, side);
    const double take_up = noise_take_up(ImageArray::Zero(side, side), weight, nullptr, centre,
                                         centre, beta, n_max, xi);
    double sum = 0.0, sum2 = 0.0;
    for (int t = 0; t < trials; ++t) {
        RandomStream r(17, std::uint64_t(t), "take-up");
        ImageArray white(side + 2, side + 2);
        for (Eigen::Index k = 0; k < white.size(); ++k) white.data()[k] = r.gaussian();
        ImageArray noise(side, side);
        for (int j = 0; j < side; ++j)
            for (int i = 0; i < side; ++i) {
                double v = 0.0;
                for (int b = 0; b < 3; ++b)
                    for (int a = 0; a < 3; ++a) v += smoothing[b] * smoothing[a] * white(j + b, i + a);
                noise(j, i) = v / 6.0;  // Σk² = 36: unit variance per pixel
            }
        const double left = side * side - fit_shapelets(noise, weight, nullptr, centre, centre,
                                                       beta, n_max).chi2;
        sum += left;
        sum2 += left * left;
    }
    const double mean = sum / trials, error = std::sqrt((sum2 / trials - mean * mean) / trials);
    const double f2_rule = real_count(n_max) * 256.0 / 36.0;
    std::cout << "  [measured] take-up " << take_up << ", Monte Carlo " << mean << " ± " << error
              << ", p·F² " << f2_rule << "\n";
    EXPECT_NEAR(mean, take_up, 4.0 * error);
    EXPECT_GT(std::abs(f2_rule - take_up), 8.0 * error);  // the exact trace is not the rule's
}

TEST(LsqNoiseTakeUp, RefusesACorrelationOfTheWrongSize) {
    const NoiseCorrelation broken{1, {1.0, 0.5}};
    EXPECT_THROW(noise_take_up(ImageArray::Zero(9, 9), ImageArray::Ones(9, 9), nullptr, 5.0, 5.0,
                               2.0, 2, broken),
                 Error);
}
