// Moments from coefficients (share/shapesim/moments.hpp) against moments of finely rendered,
// exactly pixel-integrated images, closed forms (a Gaussian), and the two independent routes
// (polar closed forms vs Cartesian coefficients × hermite_moments).
//
// Rendered moments: the model is drawn on a grid s times finer than its pixels (s·β ≥ 3), so
// the pixel-integrated samples have no aliasing (their Fourier content at the sampling
// frequency is ~e^{−(2π·3)²/2}); then Σ P = F exactly, Σ P x = ∫ x f, and
// Σ P x² = ∫ x² f + F/(12 s²) — the variance of the fine pixel box, subtracted exactly.
// The stamp extends √(2n+1) + 10 scales beyond the centre, where every φ_n is below e^{−50}.
#include "shapesim/moments.hpp"

#include "shapesim/polar.hpp"
#include "shapesim/render.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

using namespace shapesim;

namespace {

/// Raw moments of a finely rendered stamp (file comment), plus Σ|P|·(1, |x|, |x|²) as scales.
struct ImageMoments {
    RawMoments raw;
    double scale0 = 0, scale1 = 0, scale2 = 0;
};

ImageMoments rendered_moments(const ShapeletModel& model) {
    const CartesianModel cart = to_cartesian(model);
    const int s = std::max(1, int(std::ceil(3.0 / model.beta_pix)));
    const double beta_fine = s * model.beta_pix;
    const int half = int(std::ceil(beta_fine * (std::sqrt(2.0 * model.n_max + 1.0) + 10.0)));
    const int side = 2 * half + 1;
    // h(x') = f(x'/s)/s²: β → sβ and b → b/s; keep the original sub-pixel phase of the centre.
    CartesianModel fine(half + 1 + s * (model.x - std::floor(model.x)),
                        half + 1 + s * (model.y - std::floor(model.y)), beta_fine, model.n_max);
    fine.b = cart.b / s;
    const ImageArray image = render_stamp(fine, side, side);
    double f = 0, sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
    ImageMoments out;
    for (int j = 0; j < side; ++j)
        for (int i = 0; i < side; ++i) {
            const double p = image(j, i);
            const double x = (i + 1 - fine.x) / s, y = (j + 1 - fine.y) / s;
            f += p;
            sx += p * x;
            sy += p * y;
            sxx += p * x * x;
            syy += p * y * y;
            sxy += p * x * y;
            out.scale0 += std::abs(p);
            out.scale1 += std::abs(p) * std::hypot(x, y);
            out.scale2 += std::abs(p) * (x * x + y * y);
        }
    const double box = f / (12.0 * s * s);  // the fine pixel's variance, per axis
    sxx -= box;
    syy -= box;
    out.raw.flux = f;
    out.raw.z = Complex(sx, sy);
    out.raw.r2 = sxx + syy;
    out.raw.z2 = Complex(sxx - syy, 2.0 * sxy);
    return out;
}

struct NamedModel {
    std::string id;
    ShapeletModel model;
};

/// Models covering n_max 0..15 (and 20), β 0.7–6 px, sub-pixel centres: the reference file
/// plus seeded random ones. With the reference file's amplitude 0.35 the weights (n+1) of
/// Σ(n+1)a_{n,0} often drive the second moment negative: such models are no images of
/// positive things.
std::vector<NamedModel> test_models() {
    std::vector<NamedModel> out;
    for (const auto& r : test::reference_models()) out.push_back({r.id, r.model});
    std::mt19937_64 rng(20240611);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    const int orders[] = {0, 1, 2, 3, 5, 8, 11, 15, 4, 6, 9, 12, 15};
    for (int i = 0; i < 13; ++i) {
        const double beta = 0.8 * std::pow(5.0, unit(rng));  // 0.8 .. 4 px
        const bool galaxy = !(i < 8 && i % 3 == 2);
        // The last five are smooth (amplitude 0.1), so that their second moments are positive.
        const ShapeletModel model = test::random_model(
            rng, orders[i], beta, 30 + unit(rng), 40 + unit(rng), galaxy, i < 8 ? 0.35 : 0.1);
        out.push_back({"random" + std::to_string(i), model});
    }
    return out;
}

double coefficient_scale(const ShapeletModel& model) {
    double s = 0;
    for (const Complex& a : model.coeffs) s = std::max(s, std::abs(a));
    return s;
}

}  // namespace

TEST(Moments, ReferenceModelsAreFound) {
    const auto& models = test::reference_models();
    ASSERT_EQ(models.size(), 24u) << "reference/models.jsonl not found or incomplete";
}

// The record's `flux` field is 2√π β Σ a_{n,0} of the stored coefficients (README).
TEST(Moments, FluxMatchesReferenceField) {
    for (const auto& m : test::reference_models())
        EXPECT_NEAR(flux(m.model), m.flux, 1e-13 * std::abs(m.flux)) << m.id;
}

// A lone a_{0,0}: the Gaussian π^{-1/2} β^{-1} e^{−r²/2β²} a_00 — F = 2√π β a00, centroid at
// the centre, Q11 = Q22 = β², Q12 = 0, rms radius √2 β, round.
TEST(Moments, GaussianClosedForm) {
    ShapeletModel model(12.3, 4.5, 2.7, 0);
    model.at(0, 0) = 1.7;
    const Moments mo = moments(model);
    EXPECT_NEAR(mo.flux, 2 * std::sqrt(M_PI) * 2.7 * 1.7, 1e-14);
    EXPECT_NEAR(mo.x, 12.3, 1e-14);
    EXPECT_NEAR(mo.y, 4.5, 1e-14);
    EXPECT_NEAR(mo.q11, 2.7 * 2.7, 1e-13);
    EXPECT_NEAR(mo.q22, 2.7 * 2.7, 1e-13);
    EXPECT_NEAR(mo.q12, 0.0, 1e-15);
    EXPECT_NEAR(mo.rms_radius, std::sqrt(2.0) * 2.7, 1e-13);
    EXPECT_NEAR(std::abs(mo.chi), 0.0, 1e-15);
    EXPECT_NEAR(std::abs(mo.epsilon), 0.0, 1e-15);
}

// The polar closed forms and the Cartesian route agree (independent derivations), n ≤ 20.
TEST(Moments, PolarClosedFormsMatchCartesianRoute) {
    std::mt19937_64 rng(7);
    for (int n_max = 0; n_max <= 20; ++n_max)
        for (bool galaxy : {true, false}) {
            const ShapeletModel model =
                test::random_model(rng, n_max, 1.3 + 0.1 * n_max, 5.5, 6.25, galaxy);
            const RawMoments p = raw_moments(model);
            const RawMoments c = raw_moments(to_cartesian(model));
            const double beta = model.beta_pix, scale = coefficient_scale(model) * (n_max + 1);
            EXPECT_NEAR(p.flux, c.flux, 1e-13 * scale * beta) << n_max;
            EXPECT_NEAR(std::abs(p.z - c.z), 0.0, 1e-13 * scale * beta * beta) << n_max;
            EXPECT_NEAR(p.r2, c.r2, 1e-13 * scale * (n_max + 1) * std::pow(beta, 3)) << n_max;
            EXPECT_NEAR(std::abs(p.z2 - c.z2), 0.0, 1e-13 * scale * (n_max + 1) * std::pow(beta, 3))
                << n_max;
            EXPECT_NEAR(squared_norm(model), squared_norm(to_cartesian(model)),
                        1e-13 * squared_norm(model))
                << n_max;
        }
}

// Raw moments equal those of the rendered image; each tolerance is relative to the matching
// Σ|P|·|x|^p of the image (the size of the sums whose rounding it bounds). Observed: ≤ 8e-15.
TEST(Moments, RawMomentsMatchRenderedImages) {
    for (const auto& m : test_models()) {
        const ImageMoments im = rendered_moments(m.model);
        const RawMoments raw = raw_moments(m.model);
        EXPECT_NEAR(raw.flux, im.raw.flux, 5e-14 * im.scale0) << m.id;
        EXPECT_NEAR(std::abs(raw.z - im.raw.z), 0.0, 5e-14 * im.scale1) << m.id;
        EXPECT_NEAR(raw.r2, im.raw.r2, 5e-14 * im.scale2) << m.id;
        EXPECT_NEAR(std::abs(raw.z2 - im.raw.z2), 0.0, 5e-14 * im.scale2) << m.id;
    }
}

// Centroid, central moments, rms radius and both ellipticities, for every positive-flux
// model, against the same quantities computed here from the image sums.
TEST(Moments, DerivedMomentsMatchRenderedImages) {
    int shapes = 0, no_shape = 0;
    for (const auto& m : test_models()) {
        const ImageMoments im = rendered_moments(m.model);
        if (!(im.raw.flux > 0)) continue;
        const Moments mo = moments(m.model);
        const double f = im.raw.flux;
        const double dx = im.raw.z.real() / f, dy = im.raw.z.imag() / f;
        const double sxx = 0.5 * (im.raw.r2 + im.raw.z2.real()) / f;
        const double syy = 0.5 * (im.raw.r2 - im.raw.z2.real()) / f;
        const double q11 = sxx - dx * dx, q22 = syy - dy * dy;
        const double q12 = 0.5 * im.raw.z2.imag() / f - dx * dy;
        // Relative scales: Σ|P| against |f| measures cancellation within the image.
        const double cancel = im.scale0 / f, size = std::sqrt(im.scale2 / im.scale0);
        const double tol1 = 1e-11 * cancel * size, tol2 = 1e-11 * cancel * size * size;
        EXPECT_NEAR(mo.x, m.model.x + dx, tol1) << m.id;
        EXPECT_NEAR(mo.y, m.model.y + dy, tol1) << m.id;
        EXPECT_NEAR(mo.q11, q11, tol2) << m.id;
        EXPECT_NEAR(mo.q22, q22, tol2) << m.id;
        EXPECT_NEAR(mo.q12, q12, tol2) << m.id;
        EXPECT_NEAR(mo.r2_about_centre, sxx + syy, tol2) << m.id;
        const double trace = q11 + q22;
        if (std::abs(trace) < 1e-6 * size * size) continue;  // sign not decided by the test
        if (trace < 0) {
            // A negative second moment (no positive image has one): shape undefined.
            ++no_shape;
            EXPECT_TRUE(std::isnan(mo.rms_radius) && std::isnan(mo.chi.real())) << m.id;
            EXPECT_TRUE(std::isnan(mo.epsilon.real())) << m.id;
            continue;
        }
        ++shapes;
        const Complex chi = Complex(q11 - q22, 2 * q12) / trace;
        const double tol_chi = 1e-10 * cancel * size * size / trace;
        EXPECT_NEAR(mo.rms_radius, std::sqrt(trace), tol2 / std::sqrt(trace)) << m.id;
        EXPECT_NEAR(std::abs(mo.chi - chi), 0.0, tol_chi) << m.id;
        if (std::norm(chi) < 0.99) {
            const Complex eps = chi / (1.0 + std::sqrt(1.0 - std::norm(chi)));
            EXPECT_NEAR(std::abs(mo.epsilon - eps), 0.0, tol_chi) << m.id;
        } else if (std::norm(chi) > 1.01) {
            EXPECT_TRUE(std::isnan(mo.epsilon.real())) << m.id;
        }
    }
    EXPECT_GE(shapes, 15);
    EXPECT_GE(no_shape, 5);
}

// Flux ≤ 0: flux and raw moments are kept, every derived quantity is NaN (documented rule).
TEST(Moments, NonPositiveFluxGivesNaN) {
    int negative = 0;
    for (const auto& m : test::reference_models()) {
        if (m.flux > 0) continue;
        ++negative;
        const Moments mo = moments(m.model);
        EXPECT_NEAR(mo.flux, m.flux, 1e-12 * std::abs(m.flux)) << m.id;
        EXPECT_TRUE(std::isnan(mo.x) && std::isnan(mo.y) && std::isnan(mo.q11)) << m.id;
        EXPECT_TRUE(std::isnan(mo.rms_radius) && std::isnan(mo.chi.real())) << m.id;
        EXPECT_TRUE(std::isnan(mo.epsilon.imag())) << m.id;
    }
    EXPECT_EQ(negative, 2);  // M14 and M18 (README)
    ShapeletModel dipole(3, 3, 1.5, 1);
    dipole.at(1, 1) = Complex(0.4, -0.2);  // flux exactly 0
    const Moments mo = moments(dipole);
    EXPECT_EQ(mo.flux, 0.0);
    EXPECT_TRUE(std::isnan(mo.dx) && std::isnan(mo.q12));
}

// Conventions tied together: rotating the object by ρ rotates its centroid offset by e^{iρ}
// and its ellipticities by e^{2iρ}; mirroring in x conjugates them.
TEST(Moments, FollowRotationAndReflection) {
    std::mt19937_64 rng(11);
    const ShapeletModel model = test::random_model(rng, 10, 2.2, 9.0, 8.0, true, 0.03);
    ASSERT_GT(moments(model).rms_radius, 0.0);
    const Moments m0 = moments(model);
    for (double rho : {0.3, 1.9, -2.6}) {
        ShapeletModel r = model;
        int k = 0;
        for (const auto& [n, m] : polar_indices(model.n_max)) {
            (void)n;
            r.coeffs[k] *= std::polar(1.0, -m * rho);  // the documented rotation rule
            ++k;
        }
        const Moments m1 = moments(r);
        const Complex z0(m0.dx, m0.dy), z1(m1.dx, m1.dy);
        EXPECT_NEAR(std::abs(z1 - z0 * std::polar(1.0, rho)), 0.0, 1e-13);
        EXPECT_NEAR(std::abs(m1.chi - m0.chi * std::polar(1.0, 2 * rho)), 0.0, 1e-13);
        EXPECT_NEAR(std::abs(m1.epsilon - m0.epsilon * std::polar(1.0, 2 * rho)), 0.0, 1e-13);
        EXPECT_NEAR(m1.rms_radius, m0.rms_radius, 1e-13);
        EXPECT_NEAR(m1.flux, m0.flux, 1e-13);
    }
    ShapeletModel mirrored = model;
    for (Complex& a : mirrored.coeffs) a = std::conj(a);
    const Moments m2 = moments(mirrored);
    EXPECT_NEAR(std::abs(Complex(m2.dx, m2.dy) - std::conj(Complex(m0.dx, m0.dy))), 0.0, 1e-13);
    EXPECT_NEAR(std::abs(m2.chi - std::conj(m0.chi)), 0.0, 1e-13);
}

// ε and χ describe the same ellipse: |ε| = (a−b)/(a+b), |χ| = (a²−b²)/(a²+b²) with a, b the
// square roots of the eigenvalues of Q.
TEST(Moments, EllipticityConventions) {
    std::mt19937_64 rng(5);
    const ShapeletModel model = test::random_model(rng, 6, 1.9, 0.0, 0.0, true, 0.05);
    ASSERT_GT(moments(model).rms_radius, 0.0);
    const Moments mo = moments(model);
    Eigen::Matrix2d q;
    q << mo.q11, mo.q12, mo.q12, mo.q22;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(q);
    const double b = std::sqrt(eig.eigenvalues()(0)), a = std::sqrt(eig.eigenvalues()(1));
    EXPECT_NEAR(std::abs(mo.epsilon), (a - b) / (a + b), 1e-13);
    EXPECT_NEAR(std::abs(mo.chi), (a * a - b * b) / (a * a + b * b), 1e-13);
    const Eigen::Vector2d major = eig.eigenvectors().col(1);
    const double theta = std::atan2(major.y(), major.x());
    EXPECT_NEAR(std::abs(mo.epsilon - std::polar(std::abs(mo.epsilon), 2 * theta)), 0.0, 1e-12);
}
