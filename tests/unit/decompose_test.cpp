// The optimiser of decompose.hpp: n_max, β and centre from noisy stamps of known models.
#include "shapesim/decompose.hpp"

#include "shapesim/error.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/render.hpp"
#include "shapesim/rng.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <map>

using namespace shapesim;

namespace {

void report(const std::string& name, double value) {
    std::cout << "  [measured] " << name << " = " << value << "\n";
    ::testing::Test::RecordProperty(name, std::to_string(value));
}

// A galaxy-like model (a_00 dominant) centred in a stamp of `side` pixels, scaled to `flux`.
ShapeletModel galaxy(int n_max, double beta, int side, unsigned seed, double flux) {
    ShapeletModel m = test::random_model(n_max, beta, (side + 1) / 2.0 + 0.3,
                                         (side + 1) / 2.0 - 0.2, seed, true, 0.3);
    // The optimiser centres a model on its own centroid; a truth whose centroid is off its
    // basis centre has no finite expansion there. Z ∝ Σ_{n odd} √(n+1) conj a_{n,1} = 0:
    Complex z = 0.0;
    for (int n = 3; n <= n_max; n += 2) z += std::sqrt(n + 1.0) * m.at(n, 1);
    if (n_max >= 1) m.at(1, 1) = -z / std::sqrt(2.0);
    const double f = shapesim::flux(m);
    for (auto& c : m.coeffs) c *= flux / f;
    return m;
}

// The stamp of `model` plus white noise σ from RandomStream(seed, id, "noise").
ImageArray noisy(const ShapeletModel& model, int side, double sigma, std::uint64_t seed,
                 std::uint64_t id) {
    ImageArray image = render_stamp(model, side, side);
    RandomStream r(seed, id, "noise");
    for (Eigen::Index k = 0; k < image.size(); ++k) image.data()[k] += sigma * r.gaussian();
    return image;
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
}

// A noise-free model is found at its own n_max or below (fewer coefficients can already fit
// to χ²_r ≤ 1 with the weights given), with its flux.
TEST(DecomposeSynthetic, NoiseFreeModelIsRecovered) {
    const int side = 41;
    // β = 3 ≥ θ_min·√7 = 2.65: the truth is inside the optimiser's constraints.
    const ShapeletModel truth = galaxy(6, 3.0, side, 3, 1000.0);
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

// Noisy stamps of known models over a range of n_max, β and S/N: the fitted n_max does not
// exceed the truth by more than the noise allows (never by more than 2 here), χ²_r ≈ 1 where
// it converged, and the flux pulls are unbiased at S/N ≥ 100. At S/N 10 the χ² criterion
// accepts orders below the truth and these random models' higher-order flux (a_{n,0} up to
// ±40% of a_00's) is partly lost: reported, not yet solved (issue 4 stays open for it).
TEST(DecomposeSynthetic, NoisyModelsGiveUnbiasedFluxAndSensibleOrders) {
    const int side = 61;
    std::map<double, std::vector<double>> pulls;
    std::vector<double> chi2r;
    int over = 0, cases = 0, max_excess = -100;
    for (int truth_n : {2, 4, 8, 12})
        // β within the constraints (θ_min = 1 px ⇒ β ≥ √(n+1)), two sizes per order.
        for (double beta : {1.15 * std::sqrt(truth_n + 1.0), 1.6 * std::sqrt(truth_n + 1.0)})
            for (double snr : {10.0, 100.0, 1000.0})
                for (unsigned seed = 0; seed < 3; ++seed) {
                    const ShapeletModel truth = galaxy(truth_n, beta, side, 100 + seed, 1.0);
                    // σ such that the flux within 2β has S/N = 2·snr.
                    const double sigma = 1.0 / (snr * std::sqrt(4.0 * M_PI) * 2.0 * beta);
                    const ImageArray image =
                        noisy(truth, side, sigma, 7, std::uint64_t(truth_n * 1000 + seed) * 31 +
                                                         std::uint64_t(snr));
                    const ImageArray weight =
                        ImageArray::Constant(side, side, 1.0 / (sigma * sigma));
                    const Decomposition d = decompose(image, weight, nullptr, truth.x, truth.y,
                                                      beta, DecomposeOptions{});
                    ++cases;
                    const int excess = d.fit.model.n_max - truth_n;
                    max_excess = std::max(max_excess, excess);
                    if (excess > 2) ++over;
                    pulls[snr].push_back((flux(d.fit.model) - 1.0) / d.flux_error);
                    if (d.converged) chi2r.push_back(d.chi2r);
                }
    auto mean_of = [](const std::vector<double>& v) {
        double m = 0.0;
        for (double x : v) m += x / double(v.size());
        return m;
    };
    auto rms_of = [&](const std::vector<double>& v) {
        const double m = mean_of(v);
        double r = 0.0;
        for (double x : v) r += (x - m) * (x - m) / double(v.size());
        return std::sqrt(r);
    };
    report("cases", cases);
    report("n_max_over_truth_by_more_than_2", over);
    report("n_max_max_excess", max_excess);
    for (const auto& [snr, p] : pulls) {
        report("flux_pull_mean_snr" + std::to_string(int(snr)), mean_of(p));
        report("flux_pull_rms_snr" + std::to_string(int(snr)), rms_of(p));
    }
    report("converged", double(chi2r.size()));
    report("converged_chi2r_mean", mean_of(chi2r));
    EXPECT_EQ(over, 0);
    std::vector<double> bright = pulls[100.0];
    bright.insert(bright.end(), pulls[1000.0].begin(), pulls[1000.0].end());
    EXPECT_LT(std::abs(mean_of(bright)), 0.2);
    EXPECT_LT(rms_of(bright), 1.6);
    EXPECT_GT(double(chi2r.size()), 0.9 * cases);
    EXPECT_NEAR(mean_of(chi2r), 1.0, 0.05);
}

// At a galaxy's own top order the fit is just short of the data and its centroid can lead the
// recentring away (seen: 2 px in four steps, χ²_r 1 → 6): the best position seen is kept.
TEST(DecomposeSynthetic, RecentringDoesNotWanderAtTheTopOrder) {
    const int side = 32;
    int over = 0;
    double worst = 0.0;
    for (unsigned seed = 0; seed < 4; ++seed) {
        const ShapeletModel truth = galaxy(8, 3.75, side, 40 + seed, 1.0);
        const ImageArray clean = render_stamp(truth, side, side);
        const double sigma = clean.maxCoeff() / 100.0;  // peak S/N 100
        const ImageArray image = noisy(truth, side, sigma, 9, seed);
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
    const ShapeletModel truth = galaxy(4, 2.0, side, 9, 1.0);
    const double sigma = 1e-3;
    const ImageArray image = noisy(truth, side, sigma, 3, 1);
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
    const ShapeletModel truth = galaxy(4, 2.5, side, 5, 50.0);
    const double sigma = 0.01;
    Stamp stamp;
    stamp.id = "17";
    stamp.image = noisy(truth, side, sigma, 5, 17);
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
    ASSERT_TRUE(r.extra.contains("stellarity"));
    EXPECT_EQ(r.extra.at("stellarity"), 0.1);
    EXPECT_EQ(r.extra.at("stamp_hdu"), "17");
    ASSERT_TRUE(r.extra.contains("coeff_errors"));
    EXPECT_EQ(r.extra.at("coeff_errors").size(), r.coeffs.size());
    r.validate();
}
