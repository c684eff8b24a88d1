// The reference shear estimator (share/shapesim/shear_estimate.hpp) on images made here from
// the closed form of elliptical Gaussians (pixel-integrated by an 8 × 8 Gauss–Legendre rule),
// not through the shapelet code: the adaptive moments of a Gaussian are its covariance, and
// rings of sheared Gaussian galaxies seen through a Gaussian PSF give back g = 0.02 with
// |m| < 2e-3 and |c| < 1e-4 (issue 38's acceptance).
#include "shapesim/shear_estimate.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/transform.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>

using namespace shapesim;

namespace {

// ∫ over each pixel of a unit-flux Gaussian N(μ, C), μ in 0-based pixel coordinates.
ImageArray gaussian_image(int n, double mx, double my, const Eigen::Matrix2d& c) {
    static const double node[8] = {-0.9602898564975363, -0.7966664774136267, -0.5255324099163290,
                                   -0.1834346424956498, 0.1834346424956498,  0.5255324099163290,
                                   0.7966664774136267,  0.9602898564975363};
    static const double weight[8] = {0.1012285362903763, 0.2223810344533745, 0.3137066458778873,
                                     0.3626837833783620, 0.3626837833783620, 0.3137066458778873,
                                     0.2223810344533745, 0.1012285362903763};
    const Eigen::Matrix2d inv = c.inverse();
    const double norm = 1.0 / (2.0 * pi * std::sqrt(c.determinant()));
    ImageArray image(n, n);
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            double sum = 0.0;
            for (int a = 0; a < 8; ++a)
                for (int b = 0; b < 8; ++b) {
                    const Eigen::Vector2d d(i + 0.5 * node[a] - mx, j + 0.5 * node[b] - my);
                    sum += 0.25 * weight[a] * weight[b] * std::exp(-0.5 * d.dot(inv * d));
                }
            image(j, i) = norm * sum;
        }
    return image;
}

Eigen::Matrix2d covariance(double sigma, Complex epsilon) {
    // The ellipse of ε = (a−b)/(a+b) e^{2iθ}: a round Gaussian sheared by g = ε (det kept).
    const Eigen::Matrix2d s = shear_matrix(epsilon.real(), epsilon.imag());
    return sigma * sigma * s * s.transpose();
}

}  // namespace

TEST(ShearEstimate, AdaptiveMomentsOfAGaussianAreItsCovariance) {
    // Sampled at points (fine pixels approximate it): a Gaussian's pixel integral adds a box,
    // so compare with a 1/12-pixel² broader one only to first order; here the sampled form.
    const Eigen::Matrix2d c = covariance(3.0, Complex(0.2, -0.1));
    ImageArray image(64, 64);
    const Eigen::Matrix2d inv = c.inverse();
    for (int j = 0; j < 64; ++j)
        for (int i = 0; i < 64; ++i) {
            const Eigen::Vector2d d(i - 31.3, j - 32.6);
            image(j, i) = std::exp(-0.5 * d.dot(inv * d));
        }
    const auto m = adaptive_moments(image, nullptr, 30.0, 30.0, 2.0);
    ASSERT_TRUE(m);
    // The sum over integer points of a Gaussian this broad equals its integral to ~1e-30: the
    // moments are the covariance to the convergence tolerance.
    EXPECT_NEAR(m->x, 31.3, 1e-6);
    EXPECT_NEAR(m->y, 32.6, 1e-6);
    EXPECT_NEAR(m->m11, c(0, 0), 1e-6);
    EXPECT_NEAR(m->m22, c(1, 1), 1e-6);
    EXPECT_NEAR(m->m12, c(0, 1), 1e-6);
    // Nothing to measure: an empty image fails, saying why.
    std::string why;
    EXPECT_FALSE(adaptive_moments(ImageArray::Zero(32, 32), nullptr, 16, 16, 2.0, &why));
    EXPECT_EQ(why, "no positive light under the weight");
}

TEST(ShearEstimate, RingsOfGaussiansThroughAGaussianPsfGiveTheShear) {
    const Eigen::Matrix2d psf_c = covariance(1.5, Complex(0.05, 0.03));  // an elliptical PSF
    const int n = 64;
    const ImageArray psf_image = gaussian_image(n, 31.0, 31.0, psf_c);
    const auto psf = adaptive_moments(psf_image, nullptr, 31.0, 31.0, 1.5);
    ASSERT_TRUE(psf);
    // e = (1 + m) g + c from rings of 8 orientations of |ε_s| = 0.3 galaxies of σ = 2 pixels,
    // at g = (±0.02, 0) and (0, ±0.02), each galaxy off the pixel grid.
    auto mean_estimate = [&](Complex g) {
        Complex sum = 0.0;
        for (int k = 0; k < 8; ++k) {
            const Complex es = 0.3 * std::polar(1.0, 2.0 * pi * k / 8.0);
            // Lensed: ε → (ε + g)/(1 + g* ε); its covariance, plus the PSF's.
            const Complex e = (es + g) / (1.0 + std::conj(g) * es);
            const Eigen::Matrix2d observed = covariance(2.0, e) + psf_c;
            const ImageArray image = gaussian_image(n, 31.37, 30.71, observed);
            const auto m = adaptive_moments(image, nullptr, 31.0, 31.0, 2.0);
            EXPECT_TRUE(m);
            const auto estimate = linear_shear_estimate(*m, *psf);
            EXPECT_TRUE(estimate);
            sum += estimate->epsilon;
        }
        return sum / 8.0;
    };
    const double g = 0.02;
    const Complex p1 = mean_estimate(Complex(g, 0.0)), n1 = mean_estimate(Complex(-g, 0.0));
    const Complex p2 = mean_estimate(Complex(0.0, g)), n2 = mean_estimate(Complex(0.0, -g));
    const double m1 = (p1.real() - n1.real()) / (2 * g) - 1, c1 = (p1.real() + n1.real()) / 2;
    const double m2 = (p2.imag() - n2.imag()) / (2 * g) - 1, c2 = (p2.imag() + n2.imag()) / 2;
    RecordProperty("m1", std::to_string(m1));
    RecordProperty("m2", std::to_string(m2));
    RecordProperty("c1", std::to_string(c1));
    RecordProperty("c2", std::to_string(c2));
    EXPECT_LT(std::abs(m1), 2e-3) << m1;
    EXPECT_LT(std::abs(m2), 2e-3) << m2;
    EXPECT_LT(std::abs(c1), 1e-4) << c1;
    EXPECT_LT(std::abs(c2), 1e-4) << c2;
    // An object the PSF's size is unresolved: no estimate.
    EXPECT_FALSE(linear_shear_estimate(*psf, *psf));
}

TEST(ShearEstimate, PsfMomentsOfAShapeletGaussian) {
    // A round n_max 0 model of β pixels is a Gaussian of σ = β: pixel-integrated, its adaptive
    // moments are β² plus about the box's 1/12 pixel².
    ShapeletModel psf(0.0, 0.0, 2.0, 0);
    psf.coeffs[0] = 1.0;
    const AdaptiveMoments m = psf_adaptive_moments(psf);
    EXPECT_NEAR(m.m11, 4.0 + 1.0 / 12.0, 0.01);
    EXPECT_NEAR(m.m12, 0.0, 1e-9);
}
