// The optimiser of decompose.hpp: n_max, β and centre from noisy stamps of known models.
#include "shapesim/decompose.hpp"
#include "shapesim/convolve.hpp"
#include "shapesim/polar.hpp"

#include "shapesim/error.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/render.hpp"
#include "shapesim/rng.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

using namespace shapesim;

namespace {

void report(const std::string& name, double value) {
    std::cout << "  [measured] " << name << " = " << value << "\n";
    ::testing::Test::RecordProperty(name, std::to_string(value));
}

}  // namespace

TEST(DecomposeChi2, EffectiveDegreesOfFreedom) {
    ShapeletFit fit;
    fit.model = ShapeletModel(0, 0, 1.0, 4);  // 15 real parameters
    fit.chi2 = 85.0;
    fit.pixels_used = 100;
    EXPECT_DOUBLE_EQ(effective_chi2r(fit, 1.0), 1.0);            // 85 / (100 − 15)
    EXPECT_DOUBLE_EQ(effective_chi2r(fit, 2.0), 85.0 / 40.0);    // 100 − 15·4
    EXPECT_DOUBLE_EQ(effective_chi2r(fit, 10.0), 85.0);          // dof clamped at 1
}

TEST(DecomposeOptions, RefusesOutOfRangeValues) {
    DecomposeOptions o;
    o.n_max_cap = -1;
    EXPECT_THROW(o.validate(), Error);
    o = DecomposeOptions{};
    o.noise_correlation = 0.5;
    EXPECT_THROW(o.validate(), Error);
    o = DecomposeOptions{};
    o.theta_min = 0.0;
    EXPECT_THROW(o.validate(), Error);
    o = DecomposeOptions{};
    o.max_unsupported = 1.5;
    EXPECT_THROW(o.validate(), Error);
}

// A noise-free model is found at its own n_max or below (fewer coefficients can already fit
// to χ²_r ≤ 1 with the weights given), with its flux.
TEST(DecomposeSynthetic, NoiseFreeModelIsRecovered) {
    const int side = 41;
    // β = 3 ≥ θ_min·√7 = 2.65: the truth is inside the optimiser's constraints.
    const ShapeletModel truth = test::centred_galaxy(6, 3.0, side, 3, 1000.0);
    const ImageArray image = render_stamp(truth, side, side);
    const ImageArray weight = ImageArray::Constant(side, side, 1e6);  // σ = 1e-3
    // At this S/N (peak/σ ≈ 2e4) χ²_r resolves β to 1e-5 and the centre to 1e-5 px: the
    // default tolerances (1e-3 in ln β, 0.01 px), ample for real noise, are tightened.
    DecomposeOptions o;
    o.beta_tolerance = 1e-7;
    o.centre_tolerance = 1e-6;
    o.centre_iterations = 20;
    const Decomposition d = decompose(image, weight, nullptr, truth.x + 0.4, truth.y - 0.3,
                                      2.0, o);
    report("noise_free_n_max", d.fit.model.n_max);
    report("noise_free_beta", d.fit.model.beta_pix);
    report("noise_free_chi2r", d.chi2r);
    report("noise_free_fits", double(d.fits));
    EXPECT_TRUE(d.converged);
    EXPECT_LE(d.fit.model.n_max, 6);
    EXPECT_NEAR(flux(d.fit.model), 1000.0, 1e-3 * 1000.0);
    // The centre is the model's own centroid (the optimiser's definition).
    const Moments m = moments(d.fit.model);
    EXPECT_NEAR(m.x, d.fit.model.x, 0.02);
    EXPECT_NEAR(m.y, d.fit.model.y, 0.02);
}

// Noisy stamps of known models over a range of n_max, β and S/N (test::decompose_grid): the
// fitted n_max does not exceed the truth by more than the noise allows (never by more than 2
// here), χ²_r ≈ 1 where it converged, and the flux errors are honest (pull rms ≈ 1 at every
// S/N, truncation's share included). Means: unbiased at S/N ≥ 100; at S/N 10 the χ² criterion
// accepts orders below the truth and the flux they would carry (a_{n,0} of these random models
// up to ±40% of a_00's) is lost on average: about −0.5σ, reported (see `make stress` for the
// same grid with five times the cases).
TEST(DecomposeSynthetic, NoisyModelsGiveUnbiasedFluxAndSensibleOrders) {
    const test::DecomposeGrid g = test::decompose_grid(3);
    report("cases", g.cases);
    report("n_max_over_truth_by_more_than_2", g.over);
    report("n_max_max_excess", g.max_excess);
    for (double snr : {10.0, 100.0, 1000.0}) {
        const test::MeanRms p = test::mean_rms(g.pull, g.snr, [&](double s) { return s == snr; });
        report("flux_pull_mean_snr" + std::to_string(int(snr)), p.mean);
        report("flux_pull_rms_snr" + std::to_string(int(snr)), p.rms);
        EXPECT_GT(p.rms, 0.7) << "S/N " << snr;
        EXPECT_LT(p.rms, 1.5) << "S/N " << snr;
    }
    const test::MeanRms bright = test::mean_rms(g.pull, g.snr, [](double s) { return s >= 100.0; });
    const test::MeanRms faint = test::mean_rms(g.pull, g.snr, [](double s) { return s < 100.0; });
    const test::MeanRms chi2r = test::mean_rms(g.converged_chi2r, g.converged_chi2r,
                                               [](double) { return true; });
    report("converged", double(chi2r.n));
    report("converged_chi2r_mean", chi2r.mean);
    EXPECT_EQ(g.over, 0);
    EXPECT_LT(std::abs(bright.mean), 0.1 + 2.0 * bright.error);
    EXPECT_LT(std::abs(faint.mean), 1.0);
    EXPECT_GT(double(chi2r.n), 0.9 * g.cases);
    EXPECT_NEAR(chi2r.mean, 1.0, 0.05);
}

// At a galaxy's own top order the fit is just short of the data and its centroid can lead the
// recentring away (seen: 2 px in four steps, χ²_r 1 → 6): the best position seen is kept.
TEST(DecomposeSynthetic, RecentringDoesNotWanderAtTheTopOrder) {
    const int side = 32;
    int over = 0;
    double worst = 0.0;
    for (unsigned seed = 0; seed < 4; ++seed) {
        const ShapeletModel truth = test::centred_galaxy(8, 3.75, side, 40 + seed, 1.0);
        const ImageArray clean = render_stamp(truth, side, side);
        const double sigma = clean.maxCoeff() / 100.0;  // peak S/N 100
        const ImageArray image = test::noisy_stamp(truth, side, sigma, 9, seed);
        const ImageArray weight = ImageArray::Constant(side, side, 1.0 / (sigma * sigma));
        const Decomposition d =
            decompose(image, weight, nullptr, truth.x, truth.y, 3.75, DecomposeOptions{});
        for (const OrderTrial& t : d.trials)
            if (t.n_max == 8) worst = std::max(worst, t.chi2r);
        if (d.fit.model.n_max > 9) ++over;
    }
    report("top_order_worst_chi2r", worst);
    EXPECT_LT(worst, 1.3);
    EXPECT_EQ(over, 0);
}

// β stays inside the resolution and stamp constraints at the order chosen.
TEST(DecomposeSynthetic, BetaRespectsTheConstraints) {
    const int side = 25;
    const ShapeletModel truth = test::centred_galaxy(4, 2.0, side, 9, 1.0);
    const double sigma = 1e-3;
    const ImageArray image = test::noisy_stamp(truth, side, sigma, 3, 1);
    const ImageArray weight = ImageArray::Constant(side, side, 1.0 / (sigma * sigma));
    DecomposeOptions o;
    o.theta_min = 0.8;
    const Decomposition d = decompose(image, weight, nullptr, truth.x, truth.y, 2.0, o);
    for (const OrderTrial& t : d.trials) {
        const double root = std::sqrt(t.n_max + 1.0);
        EXPECT_GE(t.beta_pix / root, o.theta_min * (1 - 1e-9)) << "n_max " << t.n_max;
        const double reach = std::min(truth.x - 0.5, side + 0.5 - truth.x);
        EXPECT_LE(t.beta_pix * root, reach * (1 + 1e-9) + 0.1) << "n_max " << t.n_max;
    }
}

// A galaxy smaller than a pixel seen through a PSF five pixels wide (a round Gaussian, β 0.4
// px, through a Gaussian PSF of β 2 px; peak S/N 100, 20 noise draws): the intrinsic fit is
// held to the resolution limit on the scale the data see, √(β² + σ_psf²)/√(n+1) ≥ θ_min, not
// on its own β. It keeps the galaxy's size: the PSF-convolved model's rms radius within 1% of
// the truth's on average (held to β ≥ 1 px, as an observed-frame fit is, it comes out 10%
// larger: the ground frames' barely resolved galaxies), and every order's β respects the limit.
TEST(DecomposeSynthetic, AGalaxySmallerThanThePixelKeepsItsSizeThroughThePsf) {
    const int side = 31, seeds = 20;
    ShapeletModel truth(15.7, 15.2, 0.4, 0);
    truth.coeffs[0] = 1.0;
    ShapeletModel psf(0.0, 0.0, 2.0, 0);
    psf.coeffs[0] = 1.0;
    psf.coeffs[0] /= flux(psf);
    const ShapeletModel seen = convolve(truth, psf);
    const double sigma = render_stamp(seen, side, side).maxCoeff() / 100.0;
    const ImageArray weight = ImageArray::Constant(side, side, 1.0 / (sigma * sigma));
    DecomposeOptions o;
    o.psf = to_cartesian(psf);
    const double psf_variance = 4.0, truth_radius = moments(seen).rms_radius;
    double ratio = 0.0, beta = 0.0;
    for (int s = 0; s < seeds; ++s) {
        const Decomposition d = decompose(test::noisy_stamp(seen, side, sigma, 11, s), weight,
                                          nullptr, seen.x, seen.y, 2.0, o);
        for (const OrderTrial& t : d.trials) {
            const double limit2 = o.theta_min * o.theta_min * (t.n_max + 1.0);
            EXPECT_GE(t.beta_pix, std::sqrt(std::max(limit2 - psf_variance, limit2 / 400.0)) *
                                      (1 - 1e-9))
                << "n_max " << t.n_max;
        }
        ShapeletModel model = d.fit.model;
        ratio += moments(convolve(model, psf)).rms_radius / truth_radius / seeds;
        beta += d.fit.model.beta_pix / seeds;
    }
    report("sub_pixel_galaxy_mean_beta", beta);
    report("sub_pixel_galaxy_convolved_radius_ratio", ratio);
    EXPECT_NEAR(ratio, 1.0, 0.01);
    EXPECT_LT(beta, 0.8);
    // Held to the pixel, as before: the same galaxy's model is larger than it.
    DecomposeOptions pixel = o;
    pixel.theta_min = std::sqrt(1.0 + psf_variance);
    const Decomposition held = decompose(test::noisy_stamp(seen, side, sigma, 11, 0), weight,
                                         nullptr, seen.x, seen.y, 2.0, pixel);
    const double held_ratio = moments(convolve(held.fit.model, psf)).rms_radius / truth_radius;
    report("pixel_held_convolved_radius_ratio", held_ratio);
    EXPECT_GT(held_ratio, 1.05);
}

// Correlated noise (each pixel the mean of a 2×2 block of white noise, rescaled to unit
// variance): with per-pixel weights right, χ²/(N − p) of a fit to pure noise falls well
// below 1; with the effective dof N − p·F² (F² ≈ 3–4 for this kernel, 3.06 from 4×4 block
// sums) it is ≈ 1.
TEST(DecomposeChi2, CorrelatedNoiseNeedsTheEffectiveDof) {
    const int side = 24, n_max = 8;
    double plain = 0.0, effective = 0.0;
    const int trials = 20;
    for (int t = 0; t < trials; ++t) {
        RandomStream r(11, std::uint64_t(t), "white");
        ImageArray white(side + 1, side + 1);
        for (Eigen::Index k = 0; k < white.size(); ++k) white.data()[k] = r.gaussian();
        ImageArray image(side, side);
        for (int j = 0; j < side; ++j)
            for (int i = 0; i < side; ++i)
                image(j, i) = 0.5 * (white(j, i) + white(j + 1, i) + white(j, i + 1) +
                                     white(j + 1, i + 1));
        const ImageArray weight = ImageArray::Ones(side, side);
        const ShapeletFit fit = fit_shapelets(image, weight, nullptr, side / 2.0 + 0.5,
                                              side / 2.0 + 0.5, 2.5, n_max);
        plain += fit.chi2r / trials;
        effective += effective_chi2r(fit, 1.75) / trials;
    }
    report("pure_noise_chi2r_plain", plain);
    report("pure_noise_chi2r_effective", effective);
    EXPECT_LT(plain, 0.85);
    EXPECT_NEAR(effective, 1.0, 0.15);
}

// Galaxies (truth n_max 6, peak S/N 30) in noise smoothed by [1, 2, 1] ⊗ [1, 2, 1] (F² = 7.1,
// a correlation as smooth as a PSF-matched image's). Given the measured correlation, each fit
// counts its exact take-up: χ²_r averages 1 where the fits reach the truth's order. The p·F²
// rule overstates the take-up of the higher orders, and its χ²_r comes out above 1.
TEST(DecomposeChi2, MeasuredCorrelationGivesTheExactDegreesOfFreedom) {
    const int side = 31, trials = 12;
    NoiseCorrelation xi;
    xi.radius = 2;
    const double auto1d[5] = {1.0, 4.0, 6.0, 4.0, 1.0};  // [1, 2, 1] ⋆ [1, 2, 1]
    for (int dy = 0; dy < 5; ++dy)
        for (int dx = 0; dx < 5; ++dx) xi.values.push_back(auto1d[dy] * auto1d[dx] / 36.0);
    DecomposeOptions rule, exact;
    rule.noise_correlation = exact.noise_correlation = 16.0 / 6.0;  // F = Σk/√Σk²
    exact.correlation = xi;
    double chi2r_rule = 0.0, chi2r_exact = 0.0;
    for (int t = 0; t < trials; ++t) {
        const ShapeletModel truth = test::centred_galaxy(6, 2.8, side, 90 + t, 1.0);
        const double sigma = render_stamp(truth, side, side).maxCoeff() / 30.0;
        RandomStream r(23, std::uint64_t(t), "smoothed");
        ImageArray white(side + 2, side + 2);
        for (Eigen::Index k = 0; k < white.size(); ++k) white.data()[k] = r.gaussian();
        ImageArray image = render_stamp(truth, side, side);
        const double taps[3] = {1.0, 2.0, 1.0};
        for (int j = 0; j < side; ++j)
            for (int i = 0; i < side; ++i)
                for (int b = 0; b < 3; ++b)
                    for (int a = 0; a < 3; ++a)
                        image(j, i) += sigma * taps[b] * taps[a] * white(j + b, i + a) / 6.0;
        const ImageArray weight = ImageArray::Constant(side, side, 1.0 / (sigma * sigma));
        const Decomposition d_rule = decompose(image, weight, nullptr, truth.x, truth.y, 2.8, rule);
        const Decomposition d_exact = decompose(image, weight, nullptr, truth.x, truth.y, 2.8, exact);
        chi2r_rule += d_rule.chi2r / trials;
        chi2r_exact += d_exact.chi2r / trials;
    }
    report("smooth_noise_chi2r_f2_rule", chi2r_rule);
    report("smooth_noise_chi2r_exact", chi2r_exact);
    EXPECT_NEAR(chi2r_exact, 1.0, 0.08);
    EXPECT_GT(chi2r_rule, chi2r_exact + 0.04);  // 1.08 against 1.01
}

// White noise given as a measured correlation (ξ = δ) is the textbook fit: the same model.
TEST(DecomposeChi2, AWhiteCorrelationIsTheTextbookFit) {
    const int side = 25;
    const ShapeletModel truth = test::centred_galaxy(4, 2.5, side, 7, 1.0);
    const double sigma = render_stamp(truth, side, side).maxCoeff() / 20.0;
    const ImageArray image = test::noisy_stamp(truth, side, sigma, 3, std::uint64_t(side));
    const ImageArray weight = ImageArray::Constant(side, side, 1.0 / (sigma * sigma));
    DecomposeOptions white;
    white.correlation = NoiseCorrelation{0, {1.0}};
    const Decomposition a = decompose(image, weight, nullptr, truth.x, truth.y, 2.5, {});
    const Decomposition b = decompose(image, weight, nullptr, truth.x, truth.y, 2.5, white);
    EXPECT_EQ(a.fit.model.n_max, b.fit.model.n_max);
    EXPECT_DOUBLE_EQ(a.fit.model.beta_pix, b.fit.model.beta_pix);
    EXPECT_NEAR(a.chi2r, b.chi2r, 1e-12);
}

TEST(DecomposeErrors, AllMaskedOrBadStartThrows) {
    const int side = 15;
    const ImageArray image = ImageArray::Ones(side, side);
    const ImageArray weight = ImageArray::Ones(side, side);
    const MaskArray all = MaskArray::Ones(side, side);
    EXPECT_THROW(decompose(image, weight, &all, 8, 8, 2.0, DecomposeOptions{}), Error);
    EXPECT_THROW(decompose(image, weight, nullptr, 40, 8, 2.0, DecomposeOptions{}), Error);
    EXPECT_THROW(decompose(image, weight, nullptr, 8, 8, -1.0, DecomposeOptions{}), Error);
}

TEST(DecomposeRecord, ShiftsToTheParentAndCarriesTheSource) {
    const int side = 31;
    const ShapeletModel truth = test::centred_galaxy(4, 2.5, side, 5, 50.0);
    const double sigma = 0.01;
    Stamp stamp;
    stamp.id = "17";
    stamp.image = test::noisy_stamp(truth, side, sigma, 5, 17);
    stamp.weight = ImageArray::Constant(side, side, 1.0 / (sigma * sigma));
    stamp.mask = ImageArray::Zero(side, side);
    stamp.x0 = 101;
    stamp.y0 = 201;
    const Decomposition d =
        decompose(stamp.image, stamp.weight, nullptr, truth.x, truth.y, 2.5, DecomposeOptions{});
    SourceRecord source;
    source.id = "17";
    source.x = truth.x + 100;
    source.y = truth.y + 200;
    source.flux = 49.0;
    source.flux_err = 0.7;
    source.flags = {"blended"};
    source.stellarity = 0.1;
    source.extra["stamp_hdu"] = "17";
    const ShapeletRecord r = shapelet_record(source, d, stamp, 0.04, 25.0);
    EXPECT_EQ(r.id, "17");
    EXPECT_NEAR(r.x, d.fit.model.x + 100, 1e-12);
    EXPECT_NEAR(r.y, d.fit.model.y + 200, 1e-12);
    EXPECT_NEAR(r.beta, d.fit.model.beta_pix * 0.04, 1e-15);
    ASSERT_TRUE(r.flux.has_value());
    EXPECT_NEAR(*r.flux, 50.0, 0.5);
    EXPECT_NEAR(*r.mag, 25.0 - 2.5 * std::log10(*r.flux), 1e-12);
    EXPECT_EQ(r.flags.front(), "converged");
    EXPECT_NE(std::find(r.flags.begin(), r.flags.end(), "neighbour"), r.flags.end());
    ASSERT_TRUE(r.extra.contains("source_flux"));
    EXPECT_EQ(r.extra.at("source_flux"), 49.0);
    ASSERT_TRUE(r.extra.contains("source_flux_err"));
    EXPECT_EQ(r.extra.at("source_flux_err"), 0.7);
    EXPECT_NEAR(r.extra.at("flux_err").get<double>(), d.flux_error, 1e-15);
    EXPECT_EQ(std::find(r.flags.begin(), r.flags.end(), "noise"), r.flags.end());
    ASSERT_TRUE(r.extra.contains("stellarity"));
    EXPECT_EQ(r.extra.at("stellarity"), 0.1);
    EXPECT_EQ(r.extra.at("stamp_hdu"), "17");
    ASSERT_TRUE(r.extra.contains("coeff_errors"));
    EXPECT_EQ(r.extra.at("coeff_errors").size(), r.coeffs.size());
    r.validate();
}

// A brighter star flags a galaxy whose reach meets twice the star's Kron radius (or its
// isophote's, when larger); a fainter or farther one does not; the FWHM stands in for a
// missing Kron radius.
TEST(DecomposeRecord, NearBrightStar) {
    SourceRecord star;
    star.x = 100.0;
    star.y = 100.0;
    star.flux = 1000.0;
    star.a = 2.0;
    star.extra["kron_radius"] = 3.0;  // Kron radius 6 px: reach of the wings 12 px
    const std::vector<SourceRecord> stars{star};
    EXPECT_TRUE(near_bright_star(100.0, 115.0, 3.5, 10.0, stars));   // 15 < 3.5 + 12
    EXPECT_FALSE(near_bright_star(100.0, 116.0, 3.5, 10.0, stars));  // 16 > 15.5
    EXPECT_FALSE(near_bright_star(100.0, 115.0, 3.5, 2000.0, stars));  // galaxy brighter
    EXPECT_FALSE(near_bright_star(100.0, 115.0, 3.5, 10.0, {}));
    SourceRecord fwhm_only = star;
    fwhm_only.extra = Json::object();
    fwhm_only.fwhm = 4.0;  // radius 6 px again
    EXPECT_TRUE(near_bright_star(112.0, 100.0, 0.5, 10.0, {fwhm_only}));
    EXPECT_FALSE(near_bright_star(113.0, 100.0, 0.5, 10.0, {fwhm_only}));
    // A bright star's isophote reaches past its Kron radius: twice √(iso_area/π) = 40 px.
    SourceRecord halo = star;
    halo.extra["iso_area"] = 400.0 * M_PI;
    EXPECT_TRUE(near_bright_star(100.0, 143.0, 3.5, 10.0, {halo}));   // 43 < 3.5 + 40
    EXPECT_FALSE(near_bright_star(100.0, 144.0, 3.5, 10.0, {halo}));  // 44 > 43.5
    // … for galaxies the star outshines tenfold: a brighter one sees the Kron radius.
    EXPECT_FALSE(near_bright_star(100.0, 143.0, 3.5, 200.0, {halo}));
    EXPECT_TRUE(near_bright_star(100.0, 115.0, 3.5, 200.0, {halo}));
    halo.extra["iso_area"] = 25.0;  // inside the Kron radius: the Kron radius stands
    EXPECT_TRUE(near_bright_star(100.0, 115.0, 3.5, 10.0, {halo}));
    EXPECT_FALSE(near_bright_star(100.0, 116.0, 3.5, 10.0, {halo}));
}

// =============================================================================================
// Order choice and verdicts (the stop rules of decompose.hpp) on galaxies whose truth is known.

namespace {

bool has_flag(const ShapeletRecord& r, const char* flag) {
    return std::find(r.flags.begin(), r.flags.end(), flag) != r.flags.end();
}

// The record of decomposition `d` of a `side`² stamp at the image origin (a source "1").
ShapeletRecord record_of(const Decomposition& d, int side) {
    Stamp stamp;
    stamp.image = ImageArray::Zero(side, side);
    stamp.weight = ImageArray::Ones(side, side);
    stamp.mask = ImageArray::Zero(side, side);
    stamp.x0 = stamp.y0 = 1;
    SourceRecord source;
    source.id = "1";
    return shapelet_record(source, d, stamp, 0.04, std::nullopt);
}

// `truth` (centred in a `small`² stamp) drawn again in a `side`² stamp, same noise per pixel.
Decomposition decompose_in(const ShapeletModel& truth, int small, int side, double sigma,
                           std::uint64_t seed, const DecomposeOptions& options) {
    ShapeletModel shifted = truth;
    shifted.x += 0.5 * (side - small);
    shifted.y += 0.5 * (side - small);
    const ImageArray image = test::noisy_stamp(shifted, side, sigma, seed, std::uint64_t(side));
    const ImageArray weight = ImageArray::Constant(side, side, 1.0 / (sigma * sigma));
    return decompose(image, weight, nullptr, shifted.x, shifted.y, truth.beta_pix, options);
}

}  // namespace

// The same faint galaxy (truth n_max 4, peak S/N 10) in a tight 21² stamp and in a 121² stamp
// that is mostly sky: the order is chosen on χ², so the sky does not push it down. χ²_r alone
// would stop the large stamp two orders earlier (its sky dilutes χ²_r below the target).
TEST(DecomposeOrders, SkyInTheStampDoesNotDecideTheOrder) {
    const int small = 21, large = 121;
    double small_orders = 0.0, large_orders = 0.0, chi2r_only = 0.0;
    int differ = 0;
    const int seeds = 6;
    for (unsigned seed = 0; seed < seeds; ++seed) {
        const ShapeletModel truth = test::centred_galaxy(4, 2.5, small, 60 + seed, 1.0);
        const double sigma = render_stamp(truth, small, small).maxCoeff() / 10.0;
        const Decomposition a = decompose_in(truth, small, small, sigma, seed, DecomposeOptions{});
        const Decomposition b = decompose_in(truth, small, large, sigma, seed, DecomposeOptions{});
        small_orders += a.fit.model.n_max / double(seeds);
        large_orders += b.fit.model.n_max / double(seeds);
        differ += std::abs(a.fit.model.n_max - b.fit.model.n_max) > 2;
        // The first order at which χ²_r met its target in the large stamp.
        for (const OrderTrial& t : b.trials) {
            const double dof = double(large * large) - double(real_count(t.n_max));
            if (t.chi2r <= 1.0 + 2.0 * std::sqrt(2.0 / dof)) {
                chi2r_only += t.n_max / double(seeds);
                break;
            }
        }
    }
    report("small_stamp_mean_n_max", small_orders);
    report("large_stamp_mean_n_max", large_orders);
    report("large_stamp_mean_n_max_chi2r_rule", chi2r_only);
    EXPECT_EQ(differ, 0);
    EXPECT_GT(large_orders, small_orders - 1.0);
    EXPECT_GE(large_orders, 1.5);  // the ellipticity (m = 2) is kept, not a round Gaussian
    EXPECT_GT(large_orders, chi2r_only + 1.0);
}

// A bright galaxy with structure up to n_max 12 (peak S/N 500) is followed to its orders: no
// plateau of one or two orders stops it.
TEST(DecomposeOrders, BrightGalaxyIsFollowedToItsOrder) {
    const int side = 61;
    const ShapeletModel truth = test::centred_galaxy(12, 3.8, side, 71, 1.0);
    const double sigma = render_stamp(truth, side, side).maxCoeff() / 500.0;
    const Decomposition d = decompose_in(truth, side, side, sigma, 3, DecomposeOptions{});
    report("bright_n_max", d.fit.model.n_max);
    report("bright_chi2r", d.chi2r);
    EXPECT_GE(d.fit.model.n_max, 10);
    EXPECT_LE(d.fit.model.n_max, 14);
    EXPECT_TRUE(d.converged);
    EXPECT_FALSE(d.bad_fit);
    EXPECT_EQ(d.stop, "chi2_target");
}

// Capped well below its order, the same galaxy ends far above χ²_r = 1: stopped at the cap,
// not converged, and flagged a bad fit in its record.
TEST(DecomposeOrders, CapFarAboveTheTargetIsABadFit) {
    const int side = 61;
    const ShapeletModel truth = test::centred_galaxy(12, 3.8, side, 71, 1.0);
    const double sigma = render_stamp(truth, side, side).maxCoeff() / 500.0;
    DecomposeOptions o;
    o.n_max_cap = 4;
    const Decomposition d = decompose_in(truth, side, side, sigma, 3, o);
    report("capped_chi2r", d.chi2r);
    EXPECT_EQ(d.stop, "n_max_cap");
    EXPECT_EQ(d.fit.model.n_max, 4);
    EXPECT_FALSE(d.converged);
    EXPECT_TRUE(d.bad_fit);
    const ShapeletRecord r = record_of(d, side);
    EXPECT_TRUE(has_flag(r, "not_converged"));
    EXPECT_TRUE(has_flag(r, "n_max_cap"));
    EXPECT_TRUE(has_flag(r, "bad_fit"));
}

// Weights claiming half the true variance: χ²_r ≈ 2 at every order. Once the galaxy's orders
// are taken up the search stops ("flattened") instead of climbing to the cap on noise, and the
// verdict is honest: not converged, a bad fit.
TEST(DecomposeOrders, UnderstatedNoiseFlattensAndIsFlagged) {
    const int side = 31;
    const ShapeletModel truth = test::centred_galaxy(4, 2.5, side, 81, 1.0);
    const double sigma = render_stamp(truth, side, side).maxCoeff() / 50.0;
    const ImageArray image = test::noisy_stamp(truth, side, sigma, 4, 1);
    const ImageArray weight = ImageArray::Constant(side, side, 2.0 / (sigma * sigma));
    const Decomposition d =
        decompose(image, weight, nullptr, truth.x, truth.y, 2.5, DecomposeOptions{});
    report("understated_noise_n_max", d.fit.model.n_max);
    report("understated_noise_chi2r", d.chi2r);
    EXPECT_EQ(d.stop, "flattened");
    EXPECT_LE(d.fit.model.n_max, 8);
    EXPECT_FALSE(d.converged);
    EXPECT_TRUE(d.bad_fit);
}

// The noise's take-up of Δp more coefficients: F²(Δp + k√(2Δp)).
TEST(DecomposeOrders, NoiseUptake) {
    DecomposeOptions o;
    o.noise_correlation = 2.0;
    o.order_sigmas = 3.0;
    // n_max 2 → 4: 15 − 6 = 9 more real coefficients.
    EXPECT_DOUBLE_EQ(noise_uptake(2, 4, o), 4.0 * (9.0 + 3.0 * std::sqrt(18.0)));
    o.order_sigmas = -1.0;
    EXPECT_THROW(o.validate(), Error);
}

// Positivity: a galaxy-sized model that rings below zero (a_{2,0} = a_{0,0}, a_{4,0} = −a_{0,0}/2:
// hole 50% of its peak) is fitted faithfully, holes and all, and flagged "holes" with its
// depth; a positive elliptical profile is not, unless max_hole is below its fit's own ringing.
TEST(DecomposeOrders, ModelsRingingBelowZeroAreFlaggedHoles) {
    const int side = 41;
    ShapeletModel ringing(20.5, 20.5, 3.0, 4);
    ringing.coeffs[0] = 1.0;
    ringing.coeffs[2] = 1.0;
    ringing.coeffs[6] = -0.5;
    ASSERT_GT(hole_depth(ringing), 0.4);
    const double sigma = render_stamp(ringing, side, side).maxCoeff() / 300.0;
    const Decomposition d = decompose_in(ringing, side, side, sigma, 5, DecomposeOptions{});
    report("ringing_hole_depth", d.hole);
    EXPECT_NEAR(d.hole, hole_depth(ringing), 0.05);
    EXPECT_TRUE(d.holes);
    ShapeletModel galaxy(20.5, 20.5, 3.0, 2);  // a peaky, elliptical, positive profile
    galaxy.coeffs[0] = 1.0;
    galaxy.coeffs[2] = 0.5;
    galaxy.coeffs[3] = 0.2;
    ASSERT_LT(hole_depth(galaxy), 1e-3);
    const Decomposition g = decompose_in(galaxy, side, side, sigma, 5, DecomposeOptions{});
    report("galaxy_hole_depth", g.hole);
    EXPECT_FALSE(g.holes);
    const ShapeletRecord r = record_of(d, side);
    EXPECT_TRUE(has_flag(r, "holes"));
    EXPECT_DOUBLE_EQ(r.extra.at("hole_depth").get<double>(), d.hole);
    EXPECT_FALSE(has_flag(record_of(g, side), "holes"));
    // A shallow but wide negative ring (a_{2,0} = −0.5 a_{0,0}: 5% deep, yet 44% of the light
    // below zero) is a hole too.
    ShapeletModel wide(20.5, 20.5, 3.0, 2);
    wide.coeffs[0] = 1.0;
    wide.coeffs[2] = -0.5;
    const PixelHoles truth = pixel_holes(to_cartesian(wide));
    ASSERT_LT(truth.depth, 0.1);
    ASSERT_GT(truth.negative_light, 0.3);
    const Decomposition w = decompose_in(wide, side, side, sigma, 5, DecomposeOptions{});
    report("wide_ring_negative_light", w.negative_light);
    EXPECT_NEAR(w.negative_light, truth.negative_light, 0.05);
    EXPECT_TRUE(w.holes);
    EXPECT_DOUBLE_EQ(record_of(w, side).extra.at("negative_light").get<double>(), w.negative_light);
}

// The light a model puts where no datum constrains it. A round Gaussian (β 3 px) whose right
// side from 3.5 px off its centre is a neighbour's (masked): the fit recovers it from the
// rest, and the share of its light on the mask is the Gaussian's tail, Φ(−3.5/3) = 0.1217
// (its light beyond the stamp's edges, 6.5β away, is negligible). Masked from 0.5 px left of
// the centre, the share is Φ(0.5/3) = 0.566: more than max_unsupported, flagged.
TEST(DecomposeOrders, LightOffTheDataIsMeasuredAndFlaggedUnsupported) {
    const int side = 41;
    ShapeletModel truth(20.0, 20.0, 3.0, 0);
    truth.coeffs[0] = 100.0;
    const ImageArray image = render_stamp(truth, side, side);
    const ImageArray weight = ImageArray::Constant(side, side, 1e6);
    const auto normal_tail = [](double z) { return 0.5 * std::erfc(z / std::sqrt(2.0)); };
    for (const int first_masked : {24, 20}) {  // FITS column: its left edge at first − 0.5
        MaskArray mask = MaskArray::Zero(side, side);
        mask.rightCols(side - (first_masked - 1)).setConstant(1);
        const Decomposition d = decompose(image, weight, &mask, 20.3, 19.8, 2.5, DecomposeOptions{});
        const double expected = normal_tail((first_masked - 0.5 - truth.x) / truth.beta_pix);
        report("unsupported_light_" + std::to_string(first_masked), d.unsupported_light);
        EXPECT_NEAR(d.unsupported_light, expected, 2e-3) << "mask from column " << first_masked;
        EXPECT_EQ(d.unsupported, expected > DecomposeOptions{}.max_unsupported);
        const ShapeletRecord r = record_of(d, side);
        EXPECT_EQ(has_flag(r, "unsupported"), d.unsupported);
        EXPECT_DOUBLE_EQ(r.extra.at("unsupported_light").get<double>(), d.unsupported_light);
    }
    // Unmasked, the same galaxy's light is all on its data.
    const Decomposition clear = decompose(image, weight, nullptr, 20.3, 19.8, 2.5, DecomposeOptions{});
    EXPECT_LT(clear.unsupported_light, 1e-6);
    EXPECT_FALSE(clear.unsupported);
}

// An intrinsic fit is judged as the data see it, through its PSF: a compact model ringing
// at order 8 (a_{8,0} = a_{8,2} = 0.3 a_{0,0}, β 1.5 px; 14% holes) dips only 2% below zero
// through a Gaussian PSF of β 2 px. Fitted intrinsically, its hole is that of its convolution
// and it is not flagged at max_hole 0.03, though in its own frame its fit dips deeper.
TEST(DecomposeOrders, IntrinsicHolesAreJudgedThroughThePsf) {
    const int side = 41;
    ShapeletModel ringing(20.5, 20.5, 1.5, 8);
    ringing.coeffs[0] = 1.0;
    ringing.coeffs[20] = 0.3;  // a_{8,0} (packed polar order)
    ringing.coeffs[21] = 0.3;  // a_{8,2}
    ShapeletModel psf(0.0, 0.0, 2.0, 0);
    psf.coeffs[0] = 1.0;
    psf.coeffs[0] /= flux(psf);  // unit flux
    const ShapeletModel seen = convolve(ringing, psf);
    const double seen_hole = pixel_holes(to_cartesian(seen)).depth;
    report("ringing_through_psf_hole_depth", seen_hole);
    ASSERT_LT(seen_hole, 0.05);
    ASSERT_GT(pixel_holes(to_cartesian(ringing)).depth, 0.1);
    const double sigma = render_stamp(seen, side, side).maxCoeff() / 1000.0;
    const ImageArray weight = ImageArray::Constant(side, side, 1.0 / (sigma * sigma));
    DecomposeOptions o;
    o.psf = to_cartesian(psf);
    o.max_hole = 0.03;
    const Decomposition d =
        decompose(test::noisy_stamp(seen, side, sigma, 6, 1), weight, nullptr, seen.x, seen.y, 1.5, o);
    report("intrinsic_fit_hole_depth", d.hole);
    EXPECT_NEAR(d.hole, seen_hole, 0.02);
    EXPECT_FALSE(d.holes);
    // Judged in its own frame, the fitted intrinsic model would be flagged at max_hole 0.03.
    report("intrinsic_fit_own_frame_hole_depth", pixel_holes(to_cartesian(d.fit.model)).depth);
    EXPECT_GT(pixel_holes(to_cartesian(d.fit.model)).depth, o.max_hole);
}

// The elliptical lowest order (decompose.hpp). A faint galaxy elongated by g = (0.3, −0.15)
// (a sheared Gaussian, β 2.4 px, peak S/N 2.5 in a 41² stamp), 40 noise draws, the order
// search held at n_max 0 (no higher order can be significant) so every draw ends there: the
// models take the best-fitting shear less the noise's share in quadrature (E|ĝ|² = |g|²), so
// the models are as elongated as the galaxy: rms |ĝ| 0.319 for |g| = 0.335 (within 0.05), 0.290
// along its direction. Kept round they would all be 0; kept at the best fit, more elongated than
// the galaxy (rms 0.343). A round galaxy of the same S/N gets models of rms |ĝ| 0.114, below
// 0.4 of that (the positive part of a noise-only |g|² − tr C, 15 of 40 not round).
TEST(DecomposeElliptical, FaintElongatedGalaxyKeepsItsShape) {
    const int side = 41, seeds = 40;
    const double g1 = 0.3, g2 = -0.15, snr = 2.5;
    DecomposeOptions lowest;
    lowest.order_sigmas = 1e4;
    DecomposeOptions round_only = lowest;
    round_only.elliptical = false;
    const auto draws = [&](const ShapeletModel& truth, auto&& each) {
        const double sigma = render_stamp(truth, side, side).maxCoeff() / snr;
        const ImageArray weight = ImageArray::Constant(side, side, 1.0 / (sigma * sigma));
        for (int seed = 0; seed < seeds; ++seed) {
            const ImageArray image = test::noisy_stamp(truth, side, sigma, 500 + std::uint64_t(seed), 1);
            each(decompose(image, weight, nullptr, 21.0, 21.0, 2.0, lowest),
                 decompose(image, weight, nullptr, 21.0, 21.0, 2.0, round_only));
        }
    };
    ShapeletModel elongated = elliptical_gaussian(2.4, g1, g2);
    elongated.x = elongated.y = 21.0;
    int elliptical = 0;
    double sum_g2 = 0.0, along = 0.0;
    const double truth_g = std::hypot(g1, g2);
    draws(elongated, [&](const Decomposition& on, const Decomposition& off) {
        ASSERT_EQ(off.fit.model.n_max, 0);
        EXPECT_DOUBLE_EQ(std::abs(moments(off.fit.model).epsilon), 0.0);
        if (!on.elliptical) return;
        ++elliptical;
        sum_g2 += on.g1 * on.g1 + on.g2 * on.g2;
        along += (on.g1 * g1 + on.g2 * g2) / truth_g;
        EXPECT_EQ(on.fit.model.n_max, elliptical_order);
        EXPECT_TRUE(has_flag(record_of(on, side), "elliptical"));
        EXPECT_LT(on.chi2r, 1.2);
    });
    ShapeletModel round(21.0, 21.0, 2.4, 0);
    round.coeffs[0] = 1.0;
    int round_elliptical = 0;
    double round_g2 = 0.0;
    draws(round, [&](const Decomposition& on, const Decomposition&) {
        round_elliptical += on.elliptical;
        round_g2 += on.g1 * on.g1 + on.g2 * on.g2;
    });
    const double rms = std::sqrt(sum_g2 / seeds), round_rms = std::sqrt(round_g2 / seeds);
    report("elliptical_models", elliptical);
    report("rms_model_shear", rms);
    report("mean_shear_along_truth", along / seeds);
    report("truth_shear", truth_g);
    report("round_galaxy_elliptical_models", round_elliptical);
    report("round_galaxy_rms_model_shear", round_rms);
    EXPECT_GE(elliptical, seeds - 2);
    EXPECT_NEAR(rms, truth_g, 0.05);
    EXPECT_NEAR(along / seeds, truth_g, 0.06);
    EXPECT_LT(round_rms, 0.4 * truth_g);
}

// ------------------------------------------------------------------ joint fits (issue 17)

namespace {

// A galaxy whose colour changes across it: in the "blue" band a galaxy-like model, in the
// "red" band the same model with its centre (a_{0,0}) raised and its outer ring (a_{2,0})
// lowered, i.e. a redder core, at the same centre and β.
struct TwoBands {
    ShapeletModel blue, red;
};
TwoBands two_band_galaxy(int side, unsigned seed) {
    TwoBands g;
    g.blue = test::centred_galaxy(4, 3.0, side, seed, 1000.0);
    g.red = g.blue;
    g.red.at(0, 0) *= 2.0;
    g.red.at(2, 0) *= 0.5;
    g.red.at(4, 0) *= 0.5;
    return g;
}

// (red/blue within 3 px of the centre) / (red/blue beyond it), on the models' pixels.
double colour_gradient(const ShapeletModel& blue, const ShapeletModel& red, int side) {
    const ImageArray b = render_stamp(blue, side, side), r = render_stamp(red, side, side);
    double b_in = 0.0, r_in = 0.0, b_out = 0.0, r_out = 0.0;
    for (int j = 0; j < side; ++j)
        for (int i = 0; i < side; ++i) {
            const bool inner = std::hypot(i + 1 - blue.x, j + 1 - blue.y) < 3.0;
            (inner ? b_in : b_out) += b(j, i);
            (inner ? r_in : r_out) += r(j, i);
        }
    return (r_in / b_in) / (r_out / b_out);
}

}  // namespace

// One band through decompose_bands() is decompose(), to the bit.
TEST(DecomposeBands, OneBandIsDecompose) {
    const int side = 41;
    const ShapeletModel truth = test::centred_galaxy(4, 2.5, side, 5, 400.0);
    const ImageArray image = test::noisy_stamp(truth, side, 1.0, 11, 1);
    const ImageArray weight = ImageArray::Constant(side, side, 1.0);
    DecomposeOptions o;
    o.noise_correlation = 1.3;
    const Decomposition a = decompose(image, weight, nullptr, truth.x, truth.y, 2.0, o);
    BandStamp band;
    band.image = &image;
    band.weight = &weight;
    band.noise_correlation = 1.3;
    const Decomposition b = decompose_bands({band}, truth.x, truth.y, 2.0, o);
    EXPECT_TRUE(a.bands.empty());
    ASSERT_EQ(b.bands.size(), 1u);  // a bands file of one band still writes its band
    EXPECT_EQ(b.bands[0].fit.model.coeffs, b.fit.model.coeffs);
    EXPECT_EQ(a.fit.model.coeffs, b.fit.model.coeffs);
    EXPECT_EQ(a.fit.model.beta_pix, b.fit.model.beta_pix);
    EXPECT_EQ(a.chi2r, b.chi2r);
    EXPECT_EQ(a.flux_error, b.flux_error);
    EXPECT_EQ(a.fits, b.fits);
    EXPECT_EQ(a.stop, b.stop);
}

// Two bands of a galaxy with a colour gradient, each with its own noise: one centre and β, and
// each band's flux and core-to-ring ratio within their errors, over several noise draws; the
// record carries both bands with their zero points, the reference band's as its own.
TEST(DecomposeBands, EachBandsFluxAndColourGradientAreRecovered) {
    const int side = 41, draws = 12;
    std::vector<double> pulls;
    double gradient_fit = 0.0, gradient_truth = 0.0;
    for (int k = 0; k < draws; ++k) {
        const TwoBands g = two_band_galaxy(side, 20 + unsigned(k));
        const double sigma_blue = 1.0, sigma_red = 3.0;
        const ImageArray blue = test::noisy_stamp(g.blue, side, sigma_blue, 100 + k, 1);
        const ImageArray red = test::noisy_stamp(g.red, side, sigma_red, 100 + k, 2);
        const ImageArray w_blue = ImageArray::Constant(side, side, 1.0 / (sigma_blue * sigma_blue));
        const ImageArray w_red = ImageArray::Constant(side, side, 1.0 / (sigma_red * sigma_red));
        BandStamp b0, b1;
        b0.image = &blue, b0.weight = &w_blue, b0.signal_weight = 1.0 / sigma_blue;
        b1.image = &red, b1.weight = &w_red, b1.signal_weight = 1.0 / sigma_red;
        const Decomposition d =
            decompose_bands({b0, b1}, g.blue.x + 0.3, g.blue.y - 0.2, 2.0, DecomposeOptions{});
        ASSERT_EQ(d.bands.size(), 2u);
        EXPECT_FALSE(d.bands[1].templated) << k;  // a real gradient: its own coefficients
        EXPECT_EQ(d.bands[0].fit.model.coeffs, d.fit.model.coeffs);
        EXPECT_EQ(d.bands[0].fit.model.beta_pix, d.bands[1].fit.model.beta_pix);
        EXPECT_EQ(d.bands[0].fit.model.x, d.bands[1].fit.model.x);
        EXPECT_NEAR(d.fit.model.x, g.blue.x, 0.2);
        EXPECT_NEAR(d.fit.model.y, g.blue.y, 0.2);
        pulls.push_back((flux(d.bands[0].fit.model) - flux(g.blue)) / d.bands[0].flux_error);
        pulls.push_back((flux(d.bands[1].fit.model) - flux(g.red)) / d.bands[1].flux_error);
        // The colour gradient: red over blue within 3 px of the centre against beyond it,
        // from the models' pixels (whatever β and n_max the fit chose).
        gradient_fit += colour_gradient(d.bands[0].fit.model, d.bands[1].fit.model, side) / draws;
        gradient_truth += colour_gradient(g.blue, g.red, side) / draws;
        if (k == 0) {
            Stamp stamp;
            stamp.image = blue;
            stamp.weight = w_blue;
            stamp.mask = ImageArray::Zero(side, side);
            stamp.x0 = stamp.y0 = 1;
            SourceRecord source;
            source.id = "7";
            const ShapeletRecord r =
                shapelet_record(source, d, stamp, 0.06, 25.0, nullptr,
                                {{"b", 25.0}, {"r", 24.0}});
            ASSERT_EQ(r.bands.size(), 2u);
            EXPECT_EQ(r.bands[0].coeffs, r.coeffs);
            EXPECT_EQ(r.extra.at("band"), "b");
            EXPECT_DOUBLE_EQ(*r.bands[1].mag, 24.0 - 2.5 * std::log10(*r.bands[1].flux));
            EXPECT_DOUBLE_EQ(*r.bands[1].flux, flux(d.bands[1].fit.model));
            EXPECT_EQ(r.bands[1].extra.at("coeff_errors").size(), r.coeffs.size());
            EXPECT_EQ(ShapeletRecord::from_json(r.to_json()).to_json(), r.to_json());
            EXPECT_THROW(shapelet_record(source, d, stamp, 0.06, 25.0, nullptr, {{"b", 25.0}}),
                         Error);
        }
    }
    const double pull_rms =
        test::mean_rms(pulls, pulls, [](double) { return true; }).rms;
    report("joint_flux_pull_rms", pull_rms);
    EXPECT_LT(pull_rms, 1.6);
    for (double p : pulls) EXPECT_LT(std::abs(p), 4.0);
    report("joint_colour_gradient_fit", gradient_fit);
    report("joint_colour_gradient_truth", gradient_truth);
    EXPECT_GT(std::abs(std::log(gradient_truth)), 0.2);  // a real gradient to recover
    EXPECT_NEAR(gradient_fit / gradient_truth, 1.0, 0.05);
}

// A band where the galaxy is absent (a dropout) fits to zero within its error, as the stack's
// shape times an amplitude, and does not keep the other band from its model.
TEST(DecomposeBands, ADropoutBandFitsToZero) {
    const int side = 41;
    const ShapeletModel truth = test::centred_galaxy(4, 3.0, side, 9, 1000.0);
    ShapeletModel nothing = truth;
    for (Complex& c : nothing.coeffs) c = 0.0;
    const ImageArray seen = test::noisy_stamp(truth, side, 1.0, 7, 1);
    const ImageArray empty = test::noisy_stamp(nothing, side, 1.0, 7, 2);
    const ImageArray weight = ImageArray::Constant(side, side, 1.0);
    BandStamp a, b;
    a.image = &seen, a.weight = &weight;
    b.image = &empty, b.weight = &weight;
    const Decomposition d = decompose_bands({a, b}, truth.x, truth.y, 2.0, DecomposeOptions{});
    // Nothing of its own beyond the noise: the stack's shape times an amplitude.
    EXPECT_TRUE(d.bands[1].templated);
    EXPECT_NEAR(flux(d.bands[1].fit.model), 0.0, 4.0 * d.bands[1].flux_error);
    EXPECT_NEAR(flux(d.fit.model), 1000.0, 4.0 * d.flux_error);
    EXPECT_GE(d.fit.model.n_max, 2);
    const ImageArray small(side - 2, side);
    BandStamp c = b;
    c.image = &small;
    EXPECT_THROW(decompose_bands({a, c}, truth.x, truth.y, 2.0, DecomposeOptions{}), Error);
    EXPECT_THROW(decompose_bands({}, truth.x, truth.y, 2.0, DecomposeOptions{}), Error);
}

// A faint band that is the bright band's galaxy at a third of its flux: its own coefficients
// would be mostly noise, so it takes the stack's shape, its amplitude the right colour.
TEST(DecomposeBands, AFaintScaledCopyTakesTheStacksShape) {
    const int side = 41;
    std::vector<double> pulls;
    for (int k = 0; k < 8; ++k) {
        const ShapeletModel truth = test::centred_galaxy(6, 3.0, side, 40 + unsigned(k), 2000.0);
        ShapeletModel faint = truth;
        for (Complex& c : faint.coeffs) c /= 3.0;
        const ImageArray bright_image = test::noisy_stamp(truth, side, 1.0, 60 + k, 1);
        const ImageArray faint_image = test::noisy_stamp(faint, side, 6.0, 60 + k, 2);
        const ImageArray w1 = ImageArray::Constant(side, side, 1.0);
        const ImageArray w6 = ImageArray::Constant(side, side, 1.0 / 36.0);
        BandStamp a, b;
        a.image = &bright_image, a.weight = &w1, a.signal_weight = 1.0;
        b.image = &faint_image, b.weight = &w6, b.signal_weight = 1.0 / 6.0;
        const Decomposition d = decompose_bands({a, b}, truth.x, truth.y, 2.0, DecomposeOptions{});
        ASSERT_GE(d.fit.model.n_max, 2);
        EXPECT_TRUE(d.bands[1].templated) << k;
        // Proportional to the stack: the same shape as the bright band's, to its noise.
        const ShapeletModel& m = d.bands[1].fit.model;
        const double scale = m.coeffs[0].real() / d.fit.model.coeffs[0].real();
        for (std::size_t i = 1; i < m.coeffs.size(); ++i)
            EXPECT_NEAR(std::abs(m.coeffs[i] - scale * d.fit.model.coeffs[i]), 0.0,
                        0.05 * std::abs(m.coeffs[0]));
        pulls.push_back((flux(m) - flux(faint)) / d.bands[1].flux_error);
    }
    for (double p : pulls) EXPECT_LT(std::abs(p), 4.0);
}
