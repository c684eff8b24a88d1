// Weighted least-squares decomposition: exact recovery, honest errors, bad input.
#include "shapesim/lsq.hpp"

#include "shapesim/convolve.hpp"
#include "shapesim/error.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/polar.hpp"
#include "shapesim/render.hpp"
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
