// analytic_psf.hpp: the profiles against their closed forms (half maximum at FWHM/2, the Airy's
// first dark ring at 1.2197 λ/D and core FWHM 1.0290 λ/D, the light in a stamp against the
// closed-form encircled energy), the specs read and refused, and the shapelet models of a
// Gaussian, a Moffat and a jittered Moffat within their stated 1%.
#include "shapesim/analytic_psf.hpp"

#include "shapesim/error.hpp"
#include "shapesim/moments.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace shapesim;

namespace {

TEST(AnalyticPsf, ProfilesHalveAtHalfTheirFwhm) {
    for (const char* spec : {"gaussian:0.7", "moffat:0.7,3.5", "moffat:0.9,2.5"}) {
        const AnalyticPsf p = parse_analytic_psf(spec);
        EXPECT_NEAR(p.profile(0.5 * p.fwhm), 0.5, 1e-12) << spec;
        EXPECT_DOUBLE_EQ(p.profile(0.0), 1.0) << spec;
    }
    const AnalyticPsf airy = parse_analytic_psf("airy:0.1");
    EXPECT_LT(airy.profile(0.121967), 1e-9);           // first zero of J₁ / π
    EXPECT_NEAR(airy.nominal_fwhm() / 0.1, 1.028993, 1e-5);
    // An obscuration narrows the core.
    EXPECT_LT(parse_analytic_psf("airy:0.1,0.33").nominal_fwhm(), airy.nominal_fwhm());
}

// The image holds the profile's light in the stamp: closed-form encircled energies of the
// square's inscribed and circumscribed circles bracket its sum.
TEST(AnalyticPsf, ImagesHoldTheLightOfTheirStamp) {
    const double scale = 0.05;
    const int side = 41;  // half-width 1.025″
    const double inner = 0.5 * side * scale, outer = inner * std::sqrt(2.0);
    const AnalyticPsf moffat = parse_analytic_psf("moffat:0.7,3.5");
    const double alpha = 0.7 / (2.0 * std::sqrt(std::pow(2.0, 1.0 / 3.5) - 1.0));
    const auto moffat_ee = [&](double r) { return 1.0 - std::pow(1.0 + r * r / (alpha * alpha), -2.5); };
    const double sum = analytic_psf_image(moffat, scale, side).sum();
    EXPECT_GT(sum, moffat_ee(inner));
    EXPECT_LT(sum, moffat_ee(outer));
    const AnalyticPsf gauss = parse_analytic_psf("gaussian:0.3");
    EXPECT_NEAR(analytic_psf_image(gauss, scale, side).sum(), 1.0, 1e-6);
    // Unobscured Airy: EE(r) = 1 − J₀²(u) − J₁²(u), u = πr/(λ/D).
    const AnalyticPsf airy = parse_analytic_psf("airy:0.2");
    const auto airy_ee = [&](double r) {
        const double u = M_PI * r / 0.2;
        return 1.0 - std::pow(std::cyl_bessel_j(0.0, u), 2) - std::pow(std::cyl_bessel_j(1.0, u), 2);
    };
    const double airy_sum = analytic_psf_image(airy, 0.02, 101).sum();  // half-width 1.01″
    EXPECT_GT(airy_sum, airy_ee(1.01) - 2e-3);
    EXPECT_LT(airy_sum, airy_ee(1.01 * std::sqrt(2.0)) + 2e-3);
    // A jitter spreads the light but keeps it (a stamp wide enough).
    EXPECT_NEAR(analytic_psf_image(parse_analytic_psf("gaussian:0.3;jitter=0.1"), scale, 61).sum(),
                1.0, 1e-5);
}

TEST(AnalyticPsf, SpecsAreReadOrRefused) {
    const AnalyticPsf m = parse_analytic_psf("moffat:0.8");
    EXPECT_EQ(m.kind, AnalyticPsf::Kind::moffat);
    EXPECT_EQ(m.beta, 3.5);
    const AnalyticPsf a = parse_analytic_psf("airy:0.07,0.33;jitter=0.005");
    EXPECT_EQ(a.kind, AnalyticPsf::Kind::airy);
    EXPECT_EQ(a.obscuration, 0.33);
    EXPECT_EQ(a.jitter, 0.005);
    EXPECT_EQ(parse_analytic_psf(a.describe()).describe(), a.describe());
    for (const char* bad : {"moffat", "moffat:", "moffat:0.7,1", "gaussian:-1", "gaussian:0.7,2",
                            "airy:0.1,1", "sersic:1", "gaussian:0.7;jitter=-1", "gaussian:0.7x",
                            "gaussian:0.7;blur=1"}) {
        try {
            parse_analytic_psf(bad);
            ADD_FAILURE() << bad << " was accepted";
        } catch (const Error& e) {
            EXPECT_EQ(e.field(), "psf") << bad;
        }
    }
}

// The models: FWHM and the light within 1 and 2 FWHM within 1% of the profile's; unit flux,
// centred; a Gaussian is an n_max 0 shapelet of β = σ exactly.
TEST(AnalyticPsf, ModelsAreWithinTheirTolerance) {
    for (const char* spec : {"gaussian:0.7", "moffat:0.7,3.5", "moffat:0.7,3.5;jitter=0.1"}) {
        SCOPED_TRACE(spec);
        const AnalyticPsfModel m = analytic_psf_model(parse_analytic_psf(spec), 0.2);
        EXPECT_LT(m.worst_error(), 0.01);
        EXPECT_NEAR(flux(m.psf.model), 1.0, 1e-9);
        EXPECT_EQ(m.psf.model.x, 0.0);
        const Moments mo = moments(m.psf.model);
        EXPECT_NEAR(mo.dx, 0.0, 1e-3);
        EXPECT_NEAR(mo.dy, 0.0, 1e-3);
        EXPECT_LT(m.flux_outside, 1e-4);
    }
    const AnalyticPsfModel g = analytic_psf_model(parse_analytic_psf("gaussian:0.7"), 0.2);
    EXPECT_EQ(g.psf.n_max, 0);
    EXPECT_NEAR(g.psf.model.beta_pix * 0.2, 0.7 / 2.3548200450309493, 2e-3);
    EXPECT_NEAR(g.fwhm, 0.7, 1e-3);
}

}  // namespace
