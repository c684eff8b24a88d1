// Transforms of a model (share/shapesim/transform.hpp) against brute-force evaluation of the
// original model at transformed coordinates.
//
// Exact transforms are checked point by point (to 1e-10 of the peak; rounding gives ~1e-15).
// Projections are checked against their own reported truncation error, two ways:
//  - L2: ∫ (g − P_N g)² d²x by a Riemann sum on a grid of spacing h ≤ β/5 covering the support.
//    For these entire, Gaussian-decaying integrands the sum is spectrally accurate (its
//    aliasing error is ~exp(−½((2π/h − 2ω_max)β)²) with ω_max β ≈ √(2N+1) ≤ 10), so it must
//    reproduce the Parseval value, not merely stay below it.
//  - pixels: by Cauchy–Schwarz on each unit pixel, Σ_pixels (∫_pix (g − P_N g))² ≤ ‖g − P_N g‖²;
//    render_stamp of the projection against 10×10-point Gauss–Legendre pixel integrals of g.
#include "shapesim/transform.hpp"

#include "shapesim/basis1d.hpp"
#include "shapesim/error.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/polar.hpp"
#include "shapesim/render.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <memory>
#include <random>
#include <vector>

using namespace shapesim;

namespace {

/// b(n1, n2) order by order from the public unitary T^{(n)} (no dense n_max cache).
Eigen::MatrixXd cartesian_of(const ShapeletModel& model) {
    Eigen::MatrixXd b = Eigen::MatrixXd::Zero(model.n_max + 1, model.n_max + 1);
    for (int n = 0; n <= model.n_max; ++n) {
        const Eigen::MatrixXcd& t = polar_cartesian_matrix(n);
        for (int n1 = 0; n1 <= n; ++n1)
            for (int m = n % 2; m <= n; m += 2) {
                const double term = (model.at(n, m) * t((n + m) / 2, n1)).real();
                b(n1, n - n1) += (m == 0) ? term : 2.0 * term;
            }
    }
    return b;
}

/// Point values of a model (unintegrated), fast: Cartesian coefficients at one point.
class PointEvaluator {
public:
    explicit PointEvaluator(const ShapeletModel& model)
        : model_(model), b_(cartesian_of(model)), px_(model.n_max + 1), py_(model.n_max + 1) {}
    double operator()(double x, double y) {
        hermite_functions((x - model_.x) / model_.beta_pix, model_.n_max, px_.data());
        hermite_functions((y - model_.y) / model_.beta_pix, model_.n_max, py_.data());
        return px_.dot(b_ * py_) / model_.beta_pix;
    }

private:
    ShapeletModel model_;
    Eigen::MatrixXd b_;
    Eigen::VectorXd px_, py_;
};

/// The exact transformed image g(X) = f(c + A⁻¹(X − c − d)) of the file comment.
std::function<double(double, double)> transformed(const ShapeletModel& model,
                                                   const Eigen::Matrix2d& a,
                                                   const Eigen::Vector2d& d, double factor = 1) {
    auto eval = std::make_shared<PointEvaluator>(model);
    const Eigen::Matrix2d a_inv = a.inverse();
    const Eigen::Vector2d c(model.x, model.y);
    return [=](double x, double y) {
        const Eigen::Vector2d u = c + a_inv * (Eigen::Vector2d(x, y) - c - d);
        return factor * (*eval)(u.x(), u.y());
    };
}

/// ∫ (g − P)² d²x by a Riemann sum of spacing h over a square of half-width w about P's centre.
double grid_l2_error(const std::function<double(double, double)>& g, const ShapeletModel& p,
                     double h, double w) {
    const int k = int(std::ceil(w / h)), side = 2 * k + 1;
    // P on the grid, separably: Φ(n, i) = B_n((i − k) h; β).
    Eigen::MatrixXd phi(p.n_max + 1, side);
    for (int i = 0; i < side; ++i)
        hermite_functions((i - k) * h / p.beta_pix, p.n_max, phi.col(i).data());
    const Eigen::MatrixXd grid = phi.transpose() * cartesian_of(p) * phi / p.beta_pix;  // (i, j)
    double sum = 0.0;
    for (int i = 0; i < side; ++i)
        for (int j = 0; j < side; ++j) {
            const double diff = g(p.x + (i - k) * h, p.y + (j - k) * h) - grid(i, j);
            sum += diff * diff;
        }
    return sum * h * h;
}

/// Σ_pixels (render_stamp(P) − ∫_pixel g)² on an nx × ny stamp (FITS coordinates).
double pixel_error2(const std::function<double(double, double)>& g, const ShapeletModel& p,
                    int nx, int ny, double* peak) {
    const ImageArray rendered = render_stamp(p, nx, ny);
    double sum = 0.0;
    *peak = 0.0;
    for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) {
            const double integral = test::integrate_pixel(g, i + 1, j + 1, 10);
            const double diff = rendered(j, i) - integral;
            sum += diff * diff;
            *peak = std::max(*peak, std::abs(integral));
        }
    return sum;
}

Eigen::Matrix2d rotation(double rho) {
    Eigen::Matrix2d r;
    r << std::cos(rho), -std::sin(rho), std::sin(rho), std::cos(rho);
    return r;
}

double max_coefficient_difference(const ShapeletModel& a, const ShapeletModel& b) {
    EXPECT_EQ(a.n_max, b.n_max);
    double d = 0;
    for (size_t k = 0; k < std::min(a.coeffs.size(), b.coeffs.size()); ++k)
        d = std::max(d, std::abs(a.coeffs[k] - b.coeffs[k]));
    return d;
}

/// Max |model(p) − g(p)| over points scattered around the model, relative to max |g|.
double max_pointwise_error(const ShapeletModel& model,
                           const std::function<double(double, double)>& g, unsigned seed) {
    std::mt19937_64 rng(seed);
    const double reach = model.beta_pix * (std::sqrt(2.0 * model.n_max + 1) + 1);
    std::uniform_real_distribution<double> offset(-reach, reach);
    double err = 0, peak = 0;
    for (int i = 0; i < 400; ++i) {
        const double x = model.x + offset(rng), y = model.y + offset(rng);
        const double exact = g(x, y);
        err = std::max(err, std::abs(evaluate(model, x, y) - exact));
        peak = std::max(peak, std::abs(exact));
    }
    return err / peak;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Exact transforms.

TEST(Transform, RotationMatchesRotatedCoordinates) {
    for (int n_max : {1, 4, 9, 15}) {
        const ShapeletModel model = test::random_model(n_max, 2.3, 20.3, 18.7, 100 + n_max);
        for (double rho : {0.4, 2.0, -1.3}) {
            const ShapeletModel rotated = rotate(model, rho);
            const double err = max_pointwise_error(
                rotated, transformed(model, rotation(rho), Eigen::Vector2d::Zero()), n_max);
            EXPECT_LT(err, 1e-10) << n_max << " " << rho;
        }
    }
}

// A quarter turn about a pixel centre maps pixels onto pixels, so even the pixel-integrated
// stamps must agree: G(j, i) = F(2c − i, j) with c the centre's 0-based index.
TEST(Transform, QuarterTurnPermutesRenderedPixels) {
    const ShapeletModel model = test::random_model(12, 2.1, 17.0, 17.0, 3);
    const ImageArray f = render_stamp(model, 33, 33);
    const ImageArray g = render_stamp(rotate(model, M_PI / 2), 33, 33);
    const int c = 16;
    double err = 0;
    for (int j = 0; j < 33; ++j)
        for (int i = 0; i < 33; ++i) err = std::max(err, std::abs(g(j, i) - f(2 * c - i, j)));
    EXPECT_LT(err, 1e-13 * f.abs().maxCoeff());
}

TEST(Transform, RotateAboutAPointMovesTheCentre) {
    const ShapeletModel model = test::random_model(8, 1.8, 30.0, 12.0, 5);
    const double rho = 0.7, x0 = 25.0, y0 = 20.0;
    const ShapeletModel r = rotate_about(model, rho, x0, y0);
    // g(X) = f(p + R(−ρ)(X − p)) = f(c + R(−ρ)(X − c − d)) with d = R(ρ)(c − p) − (c − p).
    const Eigen::Vector2d cp(model.x - x0, model.y - y0);
    const Eigen::Vector2d d = rotation(rho) * cp - cp;
    EXPECT_LT(max_pointwise_error(r, transformed(model, rotation(rho), d), 1), 1e-10);
}

TEST(Transform, ReflectionsMatchMirroredCoordinates) {
    const ShapeletModel model = test::random_model(11, 2.6, 10.4, 11.9, 7);
    Eigen::Matrix2d mirror_x;
    mirror_x << 1, 0, 0, -1;
    EXPECT_LT(max_pointwise_error(reflect_x(model),
                                  transformed(model, mirror_x, Eigen::Vector2d::Zero()), 2),
              1e-10);
    for (double psi : {0.0, 0.35, 1.2, -2.0}) {
        const Eigen::Matrix2d s = rotation(psi) * mirror_x * rotation(-psi);
        EXPECT_LT(max_pointwise_error(reflect(model, psi),
                                      transformed(model, s, Eigen::Vector2d::Zero()), 3),
                  1e-10)
            << psi;
    }
    // Mirroring twice is the identity; ψ = 0 is reflect_x.
    EXPECT_EQ(max_coefficient_difference(reflect_x(reflect_x(model)), model), 0.0);
    EXPECT_LT(max_coefficient_difference(reflect(model, 0.0), reflect_x(model)), 1e-15);
}

TEST(Transform, DilationIsExact) {
    const ShapeletModel model = test::random_model(10, 1.7, 8.2, 9.1, 9);
    for (double s : {0.6, 1.0, 2.5}) {
        const Eigen::Matrix2d a = s * Eigen::Matrix2d::Identity();
        EXPECT_LT(max_pointwise_error(dilate(model, s),
                                      transformed(model, a, Eigen::Vector2d::Zero(), 1 / (s * s)),
                                      4),
                  1e-10);
        EXPECT_LT(max_pointwise_error(dilate(model, s, false),
                                      transformed(model, a, Eigen::Vector2d::Zero()), 5),
                  1e-10);
        EXPECT_NEAR(flux(dilate(model, s)), flux(model), 1e-13 * flux(model));
        EXPECT_NEAR(flux(dilate(model, s, false)), s * s * flux(model),
                    1e-13 * s * s * flux(model));
    }
}

// ---------------------------------------------------------------------------------------------
// The general projection reproduces the exact transforms.

TEST(Transform, AffineRotationReproducesPhaseRotation) {
    for (int n_max : {0, 3, 8, 15}) {
        const ShapeletModel model = test::random_model(n_max, 1.9, 4.4, 5.5, 20 + n_max);
        for (double rho : {0.3, 2.8}) {
            const Projection p = affine_transform(model, rotation(rho), Eigen::Vector2d::Zero());
            EXPECT_EQ(p.model.n_max, n_max);
            EXPECT_LT(max_coefficient_difference(p.model, rotate(model, rho)), 1e-13);
            EXPECT_LT(p.relative_error, 1e-14);
            EXPECT_TRUE(p.tolerance_met);
        }
    }
}

TEST(Transform, AffineReflectionAndScalingReproduceExactTransforms) {
    const ShapeletModel model = test::random_model(9, 2.2, 0.0, 0.0, 31);
    const double psi = 0.8;
    Eigen::Matrix2d mirror_x;
    mirror_x << 1, 0, 0, -1;
    const Eigen::Matrix2d s = rotation(psi) * mirror_x * rotation(-psi);
    const Projection pr = affine_transform(model, s, Eigen::Vector2d::Zero());
    EXPECT_LT(max_coefficient_difference(pr.model, reflect(model, psi)), 1e-13);
    // A = 1.7 I onto β_o = 1.7 β (the default) is dilate() keeping surface brightness.
    const Projection pd = affine_transform(model, 1.7 * Eigen::Matrix2d::Identity(),
                                           Eigen::Vector2d::Zero());
    EXPECT_DOUBLE_EQ(pd.model.beta_pix, 1.7 * model.beta_pix);
    EXPECT_LT(max_coefficient_difference(pd.model, dilate(model, 1.7, false)), 1e-12);
    EXPECT_NEAR(pd.norm2, 1.7 * 1.7 * squared_norm(model), 1e-13 * pd.norm2);  // |det A| ‖f‖²
}

TEST(Transform, IdentityReturnsTheModelExactly) {
    const ShapeletModel model = test::random_model(12, 2.0, 7.25, 3.5, 41);
    const OutputBasis same{model.x, model.y, model.beta_pix};
    ProjectionOptions fixed;
    fixed.n_out = 12;
    const Projection p = project_affine(model, Eigen::Matrix2d::Identity(),
                                        Eigen::Vector2d::Zero(), same, fixed);
    EXPECT_EQ(p.model.coeffs, model.coeffs);
    EXPECT_EQ(p.model.x, model.x);
    EXPECT_EQ(p.truncation_error, 0.0);
    EXPECT_EQ(translate(model, 0, 0).model.coeffs, model.coeffs);
    // A = I with the default basis moving along with the shift: the same coefficients, moved.
    const Projection moved = affine_transform(model, Eigen::Matrix2d::Identity(),
                                              Eigen::Vector2d(3.25, -1.5));
    EXPECT_EQ(moved.model.coeffs, model.coeffs);
    EXPECT_EQ(moved.model.x, model.x + 3.25);
    EXPECT_EQ(moved.model.y, model.y - 1.5);
    // Padding adds zeros; truncating drops exactly the energy of the dropped orders.
    fixed.n_out = 15;
    const Projection padded = project_affine(model, Eigen::Matrix2d::Identity(),
                                             Eigen::Vector2d::Zero(), same, fixed);
    EXPECT_EQ(padded.model.n_max, 15);
    EXPECT_EQ(padded.truncation_error, 0.0);
    fixed.n_out = 9;
    const Projection cut = project_affine(model, Eigen::Matrix2d::Identity(),
                                          Eigen::Vector2d::Zero(), same, fixed);
    EXPECT_NEAR(cut.truncation_error, squared_norm(model) - squared_norm(with_n_max(model, 9)),
                1e-15 * squared_norm(model));
}

// ---------------------------------------------------------------------------------------------
// Projections against brute force, with their reported errors.

namespace {
struct Case {
    const char* name;
    Projection projection;
    std::function<double(double, double)> exact;
};

/// The L2 and pixel checks of the file comment for one projection. Below ~1e-15·‖g‖² the
/// reported error is rounding (Parseval's difference of two O(‖g‖²) sums): the documented floor.
void check_against_brute_force(const Case& c, double beta_min, double reach, int stamp) {
    const Projection& p = c.projection;
    const double floor = 1e-15 * p.norm2;
    const double l2 = grid_l2_error(c.exact, p.model, beta_min / 5, reach);
    EXPECT_NEAR(l2, p.truncation_error, 1e-6 * p.truncation_error + floor)
        << c.name << " n_out " << p.model.n_max << " reported " << p.relative_error;
    double peak = 0;
    const double pixels = pixel_error2(c.exact, p.model, stamp, stamp, &peak);
    EXPECT_LE(pixels, p.truncation_error * (1 + 1e-6) + floor)
        << c.name << " n_out " << p.model.n_max;
}

/// Moments are inner products ∫ w g with w = 1, x, x², …: their errors are bounded through
/// ‖g − P_N g‖ by ‖w‖ over the support, which relative to ‖g‖ is a number of order one, so a
/// relative moment error must stay within a small multiple (10) of √(relative error).
double moment_tolerance(const Projection& p) {
    return 10 * std::sqrt(std::max(p.relative_error, 1e-16));
}
}  // namespace

TEST(Transform, TranslationMatchesShiftedModel) {
    for (int n_max : {4, 10}) {
        ShapeletModel model = test::random_model(n_max, 2.5, 20.4, 19.8, 50 + n_max);
        const Eigen::Vector2d d(1.3, -0.9);
        for (int n_out : {n_max, n_max + 6, n_max + 14, n_max + 24}) {
            ProjectionOptions options;
            options.n_out = n_out;
            const Projection p = translate(model, d.x(), d.y(), options);
            EXPECT_EQ(p.model.x, model.x);
            const Case c{"translate", p, transformed(model, Eigen::Matrix2d::Identity(), d)};
            check_against_brute_force(c, 2.5, 2.5 * (std::sqrt(2.0 * n_out + 1) + 9) + 2, 40);
        }
    }
}

TEST(Transform, ShearMatchesShearedCoordinates) {
    const ShapeletModel model = test::random_model(8, 2.4, 20.2, 20.6, 61);
    const double g1 = 0.25, g2 = -0.15;
    const Eigen::Matrix2d s = shear_matrix(g1, g2);
    for (int n_out : {8, 14, 22, 32}) {
        ProjectionOptions options;
        options.n_out = n_out;
        const Projection p = shear(model, g1, g2, options);
        const Case c{"shear", p, transformed(model, s, Eigen::Vector2d::Zero())};
        const double beta_min = 2.4 / s.inverse().norm();
        check_against_brute_force(c, beta_min, 2.4 * (std::sqrt(2.0 * n_out + 1) + 10), 40);
    }
}

TEST(Transform, LensingMatchesLensedCoordinatesAndKeepsFlux) {
    const ShapeletModel model = test::random_model(6, 2.0, 20.0, 21.0, 71, true, 0.1);
    Lensing lensing;
    lensing.g1 = -0.1;
    lensing.g2 = 0.2;
    lensing.kappa = 0.15;
    const double mu = magnification(lensing);
    EXPECT_NEAR(mu, 1.0 / (0.85 * 0.85 * (1 - 0.05)), 1e-15);
    const Eigen::Matrix2d a = lensing_matrix(lensing);
    // 𝒜 = (1−κ)[[1−g1, −g2], [−g2, 1+g1]] is the inverse of A.
    Eigen::Matrix2d jac;
    jac << 1 - lensing.g1, -lensing.g2, -lensing.g2, 1 + lensing.g1;
    EXPECT_LT(((1 - lensing.kappa) * jac * a - Eigen::Matrix2d::Identity()).norm(), 1e-15);
    for (bool conserve : {true, false}) {
        lensing.conserve_flux = conserve;
        ProjectionOptions options;
        options.n_out = 20;
        const Projection p = lens(model, lensing, options);
        EXPECT_DOUBLE_EQ(p.model.beta_pix, 2.0 * std::sqrt(mu));
        const double factor = conserve ? 1 / mu : 1.0;
        const Case c{"lens", p, transformed(model, a, Eigen::Vector2d::Zero(), factor)};
        check_against_brute_force(c, 2.0 / a.inverse().norm(), 2.0 * std::sqrt(mu) * 16, 40);
        const double expected = flux(model) * mu * factor;
        EXPECT_NEAR(flux(p.model), expected, moment_tolerance(p) * expected);
    }
}

TEST(Transform, ChangeBetaAndRecentreKeepTheImage) {
    const ShapeletModel model = test::random_model(9, 2.2, 20.1, 20.3, 81);
    const auto same = transformed(model, Eigen::Matrix2d::Identity(), Eigen::Vector2d::Zero());
    for (double beta : {1.6, 3.0}) {
        ProjectionOptions options;
        options.n_out = 24;
        const Projection p = change_beta(model, beta, options);
        EXPECT_EQ(p.model.beta_pix, beta);
        check_against_brute_force({"change_beta", p, same}, std::min(beta, 2.2),
                                  3.0 * (std::sqrt(49.0) + 9), 40);
    }
    ProjectionOptions options;
    options.n_out = 14;
    const Projection p = recentre(model, 21.0, 19.5, options);
    EXPECT_EQ(p.model.x, 21.0);
    EXPECT_EQ(p.model.y, 19.5);
    check_against_brute_force({"recentre", p, same}, 2.2, 2.2 * (std::sqrt(29.0) + 9) + 1, 40);
}

// A general (non-symmetric, orientation-reversing) A with a shift, onto an unrelated basis.
TEST(Transform, GeneralAffineMatchesBruteForce) {
    const ShapeletModel model = test::random_model(7, 2.1, 19.6, 20.2, 85);
    Eigen::Matrix2d a;
    a << 1.1, 0.3, 0.4, -0.8;
    const Eigen::Vector2d d(0.7, -1.2);
    const OutputBasis basis{21.1, 19.4, 2.6};
    for (int n_out : {10, 20, 30}) {
        ProjectionOptions options;
        options.n_out = n_out;
        const Projection p = project_affine(model, a, d, basis, options);
        EXPECT_NEAR(p.norm2, std::abs(a.determinant()) * squared_norm(model), 1e-14 * p.norm2);
        const double beta_min = std::min(2.6, 2.1 / a.inverse().norm());
        check_against_brute_force({"affine", p, transformed(model, a, d)}, beta_min,
                                  2.6 * (std::sqrt(2.0 * n_out + 1) + 9) + 3, 40);
    }
}

// The error falls monotonically to the rounding floor as n_out grows.
TEST(Transform, TruncationErrorVanishesAsOrderGrows) {
    const ShapeletModel model = test::random_model(8, 2.0, 0.0, 0.0, 91);
    const Eigen::Matrix2d a = shear_matrix(0.3, 0.1);
    double previous = 1.0;
    for (int n_out = 0; n_out <= 60; n_out += 4) {
        ProjectionOptions options;
        options.n_out = n_out;
        const Projection p = affine_transform(model, a, Eigen::Vector2d(1.5, -2.0), options);
        EXPECT_LE(p.relative_error, previous + 1e-15) << n_out;
        previous = p.relative_error;
    }
    EXPECT_LT(previous, 1e-13);
}

// Automatic order: the smallest N that meets the tolerance.
TEST(Transform, AutomaticOrderIsTheSmallestMeetingTolerance) {
    const ShapeletModel model = test::random_model(10, 2.3, 5.0, 5.0, 95);
    for (double tol : {1e-4, 1e-8, 1e-12}) {
        ProjectionOptions options;
        options.tolerance = tol;
        const Projection p = translate(model, 2.0, 1.0, options);
        EXPECT_TRUE(p.tolerance_met) << tol;
        EXPECT_LE(p.relative_error, tol);
        ProjectionOptions one_less;
        one_less.n_out = p.model.n_max - 1;
        EXPECT_GT(translate(model, 2.0, 1.0, one_less).relative_error, tol);
        // Same coefficients as a fixed-order projection at that order.
        ProjectionOptions same;
        same.n_out = p.model.n_max;
        EXPECT_LT(max_coefficient_difference(p.model, translate(model, 2.0, 1.0, same).model),
                  1e-14);
    }
    // A cap below the needed order: the best it can do, flagged.
    ProjectionOptions capped;
    capped.tolerance = 1e-12;
    capped.n_out_max = 12;
    const Projection p = translate(model, 2.0, 1.0, capped);
    EXPECT_EQ(p.model.n_max, 12);
    EXPECT_FALSE(p.tolerance_met);
}

// GalSim's convention: a round Gaussian sheared by g has moment ellipticity ε = g, i.e.
// (a−b)/(a+b) = |g|, and second moments β² S(g)² (Q of the sheared Gaussian is A Q Aᵀ).
// |g| = 0.64 needs n_out = 60 for 1e-12.
TEST(Transform, ShearedRoundGaussianHasEllipticityG) {
    ShapeletModel round(3.0, 4.0, 1.8, 0);
    round.at(0, 0) = 1.0;
    for (auto [g1, g2] : {std::pair{0.2, 0.0}, std::pair{-0.1, 0.35}, std::pair{0.5, 0.4}}) {
        ProjectionOptions options;
        options.tolerance = 1e-12;
        const Projection p = shear(round, g1, g2, options);
        EXPECT_TRUE(p.tolerance_met);
        const double tol = moment_tolerance(p);
        const Moments mo = moments(p.model);
        EXPECT_NEAR(mo.epsilon.real(), g1, tol);
        EXPECT_NEAR(mo.epsilon.imag(), g2, tol);
        const Eigen::Matrix2d q = 1.8 * 1.8 * shear_matrix(g1, g2) * shear_matrix(g1, g2);
        EXPECT_NEAR(mo.q11, q(0, 0), tol * q.trace());
        EXPECT_NEAR(mo.q22, q(1, 1), tol * q.trace());
        EXPECT_NEAR(mo.q12, q(0, 1), tol * q.trace());
        EXPECT_NEAR(mo.flux, flux(round), tol * flux(round));
        // Lensing with κ: same ellipticity, area × μ, flux kept.
        const Lensing lensing{g1, g2, 0.2, true};
        const Projection pl = lens(round, lensing, options);
        const Moments ml = moments(pl.model);
        const double tol_l = moment_tolerance(pl), trace = magnification(lensing) * q.trace();
        EXPECT_NEAR(std::abs(ml.epsilon - Complex(g1, g2)), 0.0, tol_l);
        EXPECT_NEAR(ml.q11 + ml.q22, trace, tol_l * trace);
        EXPECT_NEAR(ml.flux, flux(round), tol_l * flux(round));
    }
}

TEST(Transform, WorkspaceReuseGivesIdenticalResults) {
    const ShapeletModel a = test::random_model(15, 2.0, 0, 0, 97);
    const ShapeletModel b = test::random_model(5, 1.5, 0, 0, 98);
    ProjectionWorkspace ws;
    const Projection pa1 = shear(a, 0.1, 0.2, {}, &ws);
    const Projection pb = shear(b, -0.3, 0.0, {}, &ws);
    const Projection pa2 = shear(a, 0.1, 0.2, {}, &ws);
    EXPECT_EQ(pa1.model.coeffs, pa2.model.coeffs);
    EXPECT_EQ(pb.model.coeffs, shear(b, -0.3, 0.0).model.coeffs);
}

TEST(Transform, RejectsBadArguments) {
    const ShapeletModel model = test::random_model(4, 2.0, 0, 0, 99);
    Eigen::Matrix2d singular;
    singular << 1, 2, 2, 4;
    EXPECT_THROW(affine_transform(model, singular, Eigen::Vector2d::Zero()), Error);
    EXPECT_THROW(shear(model, 0.8, 0.6), Error);
    EXPECT_THROW(lens(model, Lensing{0.1, 0.0, 1.0, true}), Error);
    ProjectionOptions options;
    options.tolerance = 1e-16;
    EXPECT_THROW(translate(model, 1, 1, options), Error);
    EXPECT_THROW(change_beta(model, -1.0), Error);
    EXPECT_THROW(dilate(model, 0.0), Error);
}
