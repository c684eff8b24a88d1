// Painting scenes (scene.hpp): exactness against brute force, flux, truncation, tiles and
// threads bit for bit, noise statistics, shear recovery.
#include "shapesim/scene.hpp"
#include "render/settings.hpp"

#include "shapesim/basis1d.hpp"
#include "shapesim/error.hpp"
#include "shapesim/polar.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>

using namespace shapesim;

namespace {

void report(const std::string& name, double value) {
    std::cout << "  [measured] " << name << " = " << value << "\n";
    ::testing::Test::RecordProperty(name, std::to_string(value));
}

// f(x, y) of a Cartesian model at offsets from its centre (pixels), by the 1D basis.
double value_at(const CartesianModel& m, double dx, double dy) {
    std::vector<double> px(std::size_t(m.n_max) + 1), py(px.size());
    hermite_functions(dx / m.beta_pix, m.n_max, px.data());
    hermite_functions(dy / m.beta_pix, m.n_max, py.data());
    double v = 0.0;
    for (int a = 0; a <= m.n_max; ++a)
        for (int b = 0; b + a <= m.n_max; ++b) v += m.b(a, b) * px[std::size_t(a)] * py[std::size_t(b)];
    return v / m.beta_pix;
}

// A galaxy record at FITS (x, y) of a 0.04″ field.
ObjectRecord galaxy_record(const ShapeletModel& m, double x, double y, const std::string& id) {
    ObjectRecord r;
    r.id = id;
    r.kind = "galaxy";
    r.x = x;
    r.y = y;
    r.beta = m.beta_pix * 0.04;
    r.pixel_scale = 0.04;
    r.n_max = m.n_max;
    r.coeffs = m.coeffs;
    r.flux = flux(m);
    return r;
}

ShapeletModel psf_model() {
    ShapeletModel psf = test::random_model(6, 1.3, 0.0, 0.0, 77, true, 0.15);
    const double f = flux(psf);
    for (auto& c : psf.coeffs) c /= f;
    return psf;
}

// A crowded field: 60 galaxies of n_max 0–10 and 10 stars in a 200 × 150 field.
std::vector<PreparedObject> crowded(const SceneOptions& o) {
    SceneKernels k;
    k.galaxy = k.star = to_cartesian(psf_model());
    std::vector<PreparedObject> out;
    ConvolveWorkspace ws;
    for (int i = 0; i < 70; ++i) {
        RandomStream r(5, std::uint64_t(i), "test object");
        const double x = r.uniform(-5.0, 205.0), y = r.uniform(-5.0, 155.0);
        ObjectRecord rec;
        if (i % 7 == 6) {
            rec.id = "s" + std::to_string(i);
            rec.kind = "star";
            rec.x = x;
            rec.y = y;
            rec.flux = r.uniform(5.0, 500.0);
        } else {
            ShapeletModel m = test::random_model(i % 11, r.uniform(1.0, 4.0), 0.0, 0.0, 300 + unsigned(i), true, 0.2);
            m.coeffs[0] = r.uniform(1.0, 50.0);
            rec = galaxy_record(m, x, y, "g" + std::to_string(i));
        }
        out.push_back(prepare_object(rec, 0.04, k, o, &ws));
    }
    return out;
}

// Noise-free, stamps truncated only where a pixel would change by < 1e-9 of the peak.
SceneOptions exact_noise_free() {
    SceneOptions o;
    o.noise_free = true;
    o.truncation = 1e-9;
    return o;
}

}  // namespace

// A PSF-convolved galaxy, noise-free: every pixel equals the 32×-oversampled brute-force
// integral (32 × 32 Gauss–Legendre samples per pixel) of its convolved model to 1e-6 of the peak, and the flux is conserved to 1e-6.
TEST(Scene, PixelsEqualBruteForceAndFluxIsConserved) {
    const SceneOptions o = exact_noise_free();
    SceneKernels k;
    k.galaxy = to_cartesian(psf_model());
    const ShapeletModel g = test::random_model(8, 2.2, 0.0, 0.0, 9, true, 0.25);
    const PreparedObject p = prepare_object(galaxy_record(g, 40.3, 38.7, "g"), 0.04, k, o);
    const ImageArray image = paint({p}, Tile{1, 1, 80, 80}, o);
    double peak = image.maxCoeff(), worst = 0.0;
    // 32 samples per axis: two Gauss–Legendre points in each of 16 sub-cells (error ~h⁴; the
    // midpoint rule's h²/24·f'' would be ~1e-5 of the peak here).
    std::vector<double> nodes;
    const double half = 0.5 / std::sqrt(3.0);
    for (int a = 0; a < 16; ++a)
        for (double s : {-half, half}) nodes.push_back(-0.5 + (a + 0.5 + s) / 16.0);
    for (int j = 20; j < 60; j += 3)
        for (int i = 20; i < 60; i += 3) {
            double sum = 0.0;
            for (double u : nodes)
                for (double v : nodes)
                    sum += value_at(p.model, i + 1 + u - p.model.x, j + 1 + v - p.model.y);
            worst = std::max(worst, std::abs(sum / double(nodes.size() * nodes.size()) - image(j, i)));
        }
    report("max_pixel_error_over_peak", worst / peak);
    EXPECT_LT(worst / peak, 1e-6);
    report("flux_error_relative", std::abs(image.sum() - flux(g)) / flux(g));
    EXPECT_NEAR(image.sum(), flux(g), 1e-6 * flux(g));
    EXPECT_NEAR(p.flux, flux(g), 1e-12 * flux(g));
}

// Truncation: against the same objects rendered on whole 201² stamps, no pixel differs by
// more than truncation × the noise rms; and the stamp radius bound holds pixel by pixel.
TEST(Scene, TruncationCostsAtMostTheStatedFractionOfTheNoise) {
    SceneOptions o;
    o.noise_rms = 0.05;
    o.truncation = 1e-3;
    const std::vector<PreparedObject> objects = crowded(o);
    const Tile window{1, 1, 200, 150};
    const ImageArray cut = paint(objects, window, o);
    ImageArray full = ImageArray::Zero(150, 200);
    double worst = 0.0;
    for (const PreparedObject& p : objects) {
        ImageArray one = ImageArray::Zero(150, 200);
        add_to_image(p.model, one, PixelWindow{int(std::floor(p.model.x)) - 150,
                                               int(std::floor(p.model.y)) - 150, 301, 301});
        full += one;
        // This object alone: outside its stamp, below the threshold.
        ImageArray mine = ImageArray::Zero(150, 200);
        if (p.drawn) add_to_image(p.model, mine, p.window);
        worst = std::max(worst, (one - mine).abs().maxCoeff());
    }
    report("worst_left_out_pixel_over_noise", worst / o.noise_rms);
    EXPECT_LE(worst, o.truncation * o.noise_rms);
    const double total = (full - cut).abs().maxCoeff();
    report("worst_scene_pixel_difference_over_noise", total / o.noise_rms);
    EXPECT_LE(total, 70 * o.truncation * o.noise_rms);
}

// Noise-free, the truncation is a fraction of each model's central value (its peak pixel's
// worth): at 1e-3 … 1e-6, no pixel an object leaves out of its stamp exceeds that fraction of
// its own centre value, against the object rendered on a whole 301² stamp.
TEST(Scene, NoiseFreeTruncationIsAFractionOfThePeak) {
    for (const double truncation : {1e-3, 1e-4, 1e-5, 1e-6}) {
        SceneOptions o;
        o.noise_free = true;
        o.truncation = truncation;
        double worst = 0.0;
        for (const PreparedObject& p : crowded(o)) {
            ImageArray one = ImageArray::Zero(150, 200), mine = ImageArray::Zero(150, 200);
            add_to_image(p.model, one, PixelWindow{int(std::floor(p.model.x)) - 150,
                                                   int(std::floor(p.model.y)) - 150, 301, 301});
            if (p.drawn) add_to_image(p.model, mine, p.window);
            worst = std::max(worst, (one - mine).abs().maxCoeff() / truncation_threshold(p.model, o));
        }
        report("noise_free_left_out_over_threshold_" + std::to_string(int(-std::log10(truncation))), worst);
        EXPECT_LE(worst, 1.0) << truncation;
    }
}

// A mosaic of 3×3 tiles equals the whole image bit for bit, with white, correlated and
// photon noise; so do 1 and 3 threads.
TEST(Scene, TilesAndThreadsAreBitIdentical) {
    for (double factor : {1.0, 1.8}) {
        SceneOptions o;
        o.noise_rms = 0.05;
        o.noise_correlation = factor;
        o.gain = 40.0;
        o.seed = 21;
        const std::vector<PreparedObject> objects = crowded(o);
        const Tile whole{1, 1, 200, 150};
        ImageArray image = paint(objects, whole, o);
        add_noise(image, whole, 200, o);
        SceneOptions threaded = o;
        threaded.threads = 3;
        ImageArray again = paint(objects, whole, threaded);
        add_noise(again, whole, 200, threaded);
        EXPECT_TRUE((again == image).all()) << "threads, F = " << factor;
        for (int j = 0; j < 3; ++j)
            for (int i = 0; i < 3; ++i) {
                const Tile t{1 + 67 * i, 1 + 50 * j, i == 2 ? 200 : 67 * (i + 1), 50 * (j + 1)};
                ImageArray tile = paint(objects, t, o);
                add_noise(tile, t, 200, o);
                const ImageArray expect = image.block(t.y0 - 1, t.x0 - 1, t.y1 - t.y0 + 1, t.x1 - t.x0 + 1);
                EXPECT_TRUE((tile == expect).all()) << "tile " << i << "," << j << " F " << factor;
            }
    }
}

// clip_negative: a galaxy's pixels below zero become zero, the rest untouched, and paint
// reports the light removed (the whole stamp's, once) and the deepest pixel. Clipping works on
// whole stamps, so threads and tiles still give identical bits and identical reports.
TEST(Scene, ClippedNegativeLightIsExactAndTileInvariant) {
    const SceneOptions o = exact_noise_free();
    SceneKernels k;
    k.galaxy = to_cartesian(psf_model());
    ShapeletModel g(0.0, 0.0, 2.5, 4);
    g.coeffs[0] = 10.0;
    g.coeffs[2] = 6.0;  // a_{2,0} and a_{4,0} (packed polar order): a ring dipping below zero
    g.coeffs[6] = 4.0;
    const std::vector<PreparedObject> one = {prepare_object(galaxy_record(g, 40.3, 38.7, "g"), 0.04, k, o)};
    const Tile window{1, 1, 80, 80};
    const ImageArray exact = paint(one, window, o);
    ASSERT_LT(exact.minCoeff(), -1e-3 * exact.maxCoeff());
    SceneOptions clip = o;
    clip.clip_negative = true;
    std::vector<ClippedLight> clipped;
    const ImageArray image = paint(one, window, clip, &clipped);
    EXPECT_TRUE((image == exact.cwiseMax(0.0)).all());
    ASSERT_EQ(clipped.size(), 1u);
    const double negative = -exact.cwiseMin(0.0).sum();
    report("clipped_flux_fraction", negative / one[0].flux);
    EXPECT_NEAR(clipped[0].flux, negative, 1e-12 * negative);
    EXPECT_EQ(clipped[0].deepest, exact.minCoeff());
    EXPECT_NEAR(image.sum(), one[0].flux + clipped[0].flux, 1e-9 * one[0].flux);

    SceneOptions crowd;
    crowd.noise_rms = 0.05;
    crowd.clip_negative = true;
    const std::vector<PreparedObject> objects = crowded(crowd);
    const Tile whole{1, 1, 200, 150};
    std::vector<ClippedLight> first, threaded_report;
    const ImageArray all = paint(objects, whole, crowd, &first);
    SceneOptions threaded = crowd;
    threaded.threads = 3;
    EXPECT_TRUE((paint(objects, whole, threaded, &threaded_report) == all).all());
    int with_holes = 0;
    for (std::size_t i = 0; i < objects.size(); ++i) {
        EXPECT_EQ(first[i].flux, threaded_report[i].flux) << i;
        with_holes += first[i].flux > 0.0;
        if (objects[i].kind == "star") {
            EXPECT_EQ(first[i].flux, 0.0) << i;
        }
    }
    EXPECT_GT(with_holes, 0);
    for (int j = 0; j < 2; ++j)
        for (int i = 0; i < 2; ++i) {
            const Tile t{1 + 100 * i, 1 + 75 * j, 100 * (i + 1), 75 * (j + 1)};
            const ImageArray expect = all.block(t.y0 - 1, t.x0 - 1, 75, 100);
            EXPECT_TRUE((paint(objects, t, crowd) == expect).all()) << "tile " << i << "," << j;
        }
}

// Noise: over 400 realisations, (noisy − clean) has mean 0 and variance σ² + s/gain in
// empty, faint and bright pixels, within 4 standard errors; correlated noise keeps σ² per
// pixel and gives 4×4 block sums the requested factor F.
TEST(Scene, NoiseMatchesItsModelInEveryPixelClass) {
    SceneOptions o;
    o.noise_rms = 0.02;
    o.gain = 500.0;
    o.noise_free = true;
    ShapeletModel g(0.0, 0.0, 4.0, 0);
    g.at(0, 0) = 2.0;  // flux 28.4: peak pixel ≈ 0.28, σ_photon ≈ 0.024 there
    const PreparedObject p = prepare_object(galaxy_record(g, 16.5, 16.5, "g"), 0.04, {}, o);
    const Tile window{1, 1, 32, 32};
    const ImageArray clean = paint({p}, window, o);
    o.noise_free = false;
    const int runs = 400;
    ImageArray sum = ImageArray::Zero(32, 32), sum2 = ImageArray::Zero(32, 32);
    for (int k = 0; k < runs; ++k) {
        o.seed = std::uint64_t(k);
        ImageArray noisy = clean;
        add_noise(noisy, window, 32, o);
        const ImageArray d = noisy - clean;
        sum += d;
        sum2 += d * d;
    }
    struct Class {
        const char* name;
        double lo, hi;
        double mean = 0.0, var = 0.0, model = 0.0;
        int n = 0;
    };
    Class classes[3] = {{"empty", -1.0, 1e-6}, {"faint", 1e-3, 0.02}, {"bright", 0.1, 10.0}};
    for (Class& c : classes) {
        for (int j = 0; j < 32; ++j)
            for (int i = 0; i < 32; ++i) {
                const double s = clean(j, i);
                if (s < c.lo || s >= c.hi) continue;
                const double mean = sum(j, i) / runs, var = sum2(j, i) / runs - mean * mean;
                const double model = o.noise_rms * o.noise_rms + s / o.gain;
                // Per pixel: mean within 4σ/√runs; variance ratio averaged over the class.
                EXPECT_LT(std::abs(mean), 4.0 * std::sqrt(model / runs)) << c.name;
                c.var += var / model;
                ++c.n;
            }
        ASSERT_GT(c.n, 10) << c.name;
        c.var /= c.n;
        report(std::string("variance_over_model_") + c.name, c.var);
        // var/model of one pixel scatters by √(2/runs) = 0.07; a class of n pixels by less
        // (pixels independent): allow 4σ of the mean.
        EXPECT_NEAR(c.var, 1.0, 4.0 * std::sqrt(2.0 / runs / c.n)) << c.name;
    }
    // Correlated background alone.
    SceneOptions c;
    c.noise_rms = 1.0;
    c.noise_correlation = 1.84;
    ImageArray n = ImageArray::Zero(512, 512);
    add_noise(n, Tile{1, 1, 512, 512}, 512, c);
    double var = n.square().mean() - n.mean() * n.mean(), blocks = 0.0;
    int count = 0;
    for (int j = 0; j + 4 <= 512; j += 4)
        for (int i = 0; i + 4 <= 512; i += 4, ++count) blocks += std::pow(n.block(j, i, 4, 4).sum(), 2);
    const double factor = std::sqrt(blocks / count / 16.0);
    report("correlated_pixel_variance", var);
    report("correlated_block_factor", factor);
    EXPECT_NEAR(var, 1.0, 0.02);
    EXPECT_NEAR(factor, 1.84, 0.05);
    EXPECT_EQ(correlated_noise_kernel_edge(1.0), 0.0);
    EXPECT_THROW(correlated_noise_kernel_edge(3.0), Error);
}

// Shear: a round galaxy sheared by g = (0.05, −0.03), rendered noise-free without a PSF,
// gives g back from its pixel moments to 1% of |g|.
TEST(Scene, ShearIsRecoveredFromImageMoments) {
    SceneOptions o;
    o.noise_free = true;
    o.truncation = 1e-10;
    o.lensing = Lensing{0.05, -0.03, 0.0, true};
    ShapeletModel round(0.0, 0.0, 6.0, 4);
    round.at(0, 0) = 1.0;
    round.at(2, 0) = 0.3;
    round.at(4, 0) = -0.1;
    const PreparedObject p = prepare_object(galaxy_record(round, 100.5, 100.5, "g"), 0.04, {}, o);
    const ImageArray image = paint({p}, Tile{1, 1, 200, 200}, o);
    double f = 0.0, mx = 0.0, my = 0.0;
    for (int j = 0; j < 200; ++j)
        for (int i = 0; i < 200; ++i) {
            f += image(j, i);
            mx += image(j, i) * (i + 1);
            my += image(j, i) * (j + 1);
        }
    mx /= f;
    my /= f;
    double q11 = 0.0, q22 = 0.0, q12 = 0.0;
    for (int j = 0; j < 200; ++j)
        for (int i = 0; i < 200; ++i) {
            const double dx = i + 1 - mx, dy = j + 1 - my, v = image(j, i) / f;
            q11 += v * dx * dx;
            q22 += v * dy * dy;
            q12 += v * dx * dy;
        }
    q11 -= 1.0 / 12.0;  // the pixel's own second moment
    q22 -= 1.0 / 12.0;
    const Complex chi((q11 - q22) / (q11 + q22), 2.0 * q12 / (q11 + q22));
    const Complex g = chi / (1.0 + std::sqrt(1.0 - std::norm(chi)));
    report("shear_g1_measured", g.real());
    report("shear_g2_measured", g.imag());
    const double err = std::abs(g - Complex(0.05, -0.03));
    EXPECT_LT(err, 0.01 * std::abs(Complex(0.05, -0.03)));
    EXPECT_LT(p.lensing_error, 1e-8);
}

// The stamp radius bound: random models, pixels wholly outside R are ≤ the threshold and R is
// not wasteful (some pixel within R + 3 px exceeds threshold/1000).
TEST(Scene, StampRadiusBoundHolds) {
    for (int k = 0; k < 20; ++k) {
        const ShapeletModel m = test::random_model(k % 12, 1.0 + 0.2 * k, 0.0, 0.0, 40 + unsigned(k), true, 0.3);
        CartesianModel c = to_cartesian(m);
        const double threshold = 1e-4 * std::abs(c.b(0, 0)) / c.beta_pix;
        const double r = stamp_radius(c, threshold);
        ASSERT_GT(r, 0.0);
        const int side = 2 * int(r) + 81;
        c.x = c.y = (side + 1) / 2.0;
        const ImageArray image = render_stamp(c, side, side);
        double outside = 0.0, near = 0.0;
        for (int j = 0; j < side; ++j)
            for (int i = 0; i < side; ++i) {
                const double dx = std::abs(i + 1 - c.x), dy = std::abs(j + 1 - c.y);
                const double v = std::abs(image(j, i));
                if (std::max(dx, dy) - 0.5 >= r) outside = std::max(outside, v);
                else if (std::max(dx, dy) + 3.0 >= r) near = std::max(near, v);
            }
        EXPECT_LE(outside, threshold) << k;
        EXPECT_GT(near, threshold / 1000.0) << k;
    }
}

// The difference kernel: a galaxy that already holds an old PSF, convolved with new ⊘ old,
// matches the galaxy convolved with the new PSF directly (to the kernel's own residual).
TEST(Scene, DifferenceKernelReobservesWithABroaderPsf) {
    SceneOptions o;
    o.noise_free = true;
    o.truncation = 1e-8;
    ShapeletModel old_psf(0.0, 0.0, 1.0, 2), new_psf(0.0, 0.0, 1.6, 2);
    old_psf.at(0, 0) = 1.0 / (2.0 * std::sqrt(M_PI) * 1.0);
    old_psf.at(2, 2) = Complex(0.02, 0.01);
    new_psf.at(0, 0) = 1.0 / (2.0 * std::sqrt(M_PI) * 1.6);
    new_psf.at(2, 0) = 0.01;
    const ShapeletModel galaxy = test::random_model(6, 2.0, 0.0, 0.0, 8, true, 0.2);
    const ShapeletModel observed = convolve(galaxy, old_psf);  // what a real image holds
    const DifferenceKernel k = difference_kernel(old_psf, new_psf, 8);
    SceneKernels via_kernel, direct;
    via_kernel.galaxy = to_cartesian(k.kernel);
    direct.galaxy = to_cartesian(new_psf);
    const ImageArray a =
        paint({prepare_object(galaxy_record(observed, 50.2, 49.7, "g"), 0.04, via_kernel, o)},
              Tile{1, 1, 100, 100}, o);
    const ImageArray b =
        paint({prepare_object(galaxy_record(galaxy, 50.2, 49.7, "g"), 0.04, direct, o)},
              Tile{1, 1, 100, 100}, o);
    const double err = (a - b).abs().maxCoeff() / b.maxCoeff();
    report("difference_kernel_residual", k.report.relative_residual);
    report("difference_kernel_max_pixel_error_over_peak", err);
    EXPECT_LT(err, 1e-3);
}

// Intrinsic galaxies are drawn through the PSF itself (not the galaxy kernel) and never
// sharper than the PSF they were fitted through: with psf_beta above the target PSF's β the
// model is first smoothed by the Gaussian of scale √(b_seen² − b_target²); below it, not.
TEST(Scene, IntrinsicModelsThroughThePsfNeverSharperThanSeen) {
    SceneOptions o;
    o.noise_free = true;
    SceneKernels k;
    const ShapeletModel psf = psf_model();
    k.star = to_cartesian(psf);
    const ShapeletModel g = test::random_model(6, 2.0, 0.0, 0.0, 12, true, 0.25);
    ObjectRecord r = galaxy_record(g, 30.0, 30.0, "g");
    r.extra["frame"] = "intrinsic";
    const auto coefficients_match = [](const CartesianModel& a, const CartesianModel& b) {
        return a.n_max == b.n_max && std::abs(a.beta_pix - b.beta_pix) < 1e-12 * b.beta_pix &&
               (a.b - b.b).cwiseAbs().maxCoeff() < 1e-12 * b.b.cwiseAbs().maxCoeff();
    };
    ShapeletModel placed = g;
    placed.x = placed.y = 30.0;
    // No psf_beta, or one sharper than the target: the PSF alone.
    const CartesianModel through_psf = convolve(to_cartesian(placed), k.star.value());
    EXPECT_TRUE(coefficients_match(prepare_object(r, 0.04, k, o).model, through_psf));
    r.extra["psf_beta"] = 0.5 * psf.beta_pix * 0.04;
    EXPECT_TRUE(coefficients_match(prepare_object(r, 0.04, k, o).model, through_psf));
    // Seen through a PSF twice as broad: smoothed to its scale first.
    r.extra["psf_beta"] = 2.0 * psf.beta_pix * 0.04;
    CartesianModel gaussian(0.0, 0.0, std::sqrt(3.0) * psf.beta_pix, 0);
    gaussian.b(0, 0) = 1.0;
    gaussian.b(0, 0) = 1.0 / flux(to_polar(gaussian));
    const CartesianModel smoothed = convolve(convolve(to_cartesian(placed), gaussian), k.star.value());
    const PreparedObject p = prepare_object(r, 0.04, k, o);
    EXPECT_TRUE(coefficients_match(p.model, smoothed));
    EXPECT_NEAR(flux(to_polar(p.model)), flux(g), 1e-9 * flux(g));  // unit-flux kernels
    // Without a PSF an intrinsic model is refused.
    EXPECT_THROW(prepare_object(r, 0.04, SceneKernels{}, o), Error);
}

namespace {

// The crowded field's records (crowded() prepares the same objects one by one).
// The crowded field's geometry (200 × 150 at 0.04″) and the kernels that draw it.
FieldGeometry crowded_field() {
    FieldGeometry field;
    field.nx = 200;
    field.ny = 150;
    field.pixel_scale = 0.04;
    return field;
}
SceneKernels psf_kernels() {
    SceneKernels k;
    k.galaxy = k.star = to_cartesian(psf_model());
    return k;
}

std::vector<ObjectRecord> crowded_records() {
    std::vector<ObjectRecord> records;
    for (int i = 0; i < 70; ++i) {
        RandomStream r(5, std::uint64_t(i), "test object");
        const double x = r.uniform(-5.0, 205.0), y = r.uniform(-5.0, 155.0);
        ObjectRecord rec;
        if (i % 7 == 6) {
            rec.id = "s" + std::to_string(i);
            rec.kind = "star";
            rec.x = x;
            rec.y = y;
            rec.flux = r.uniform(5.0, 500.0);
            rec.mag = 25.0 - 2.5 * std::log10(rec.flux);
        } else {
            ShapeletModel m = test::random_model(i % 11, r.uniform(1.0, 4.0), 0.0, 0.0, 300 + unsigned(i), true, 0.2);
            m.coeffs[0] = r.uniform(1.0, 50.0);
            rec = galaxy_record(m, x, y, "g" + std::to_string(i));
            if (rec.flux > 0.0) rec.mag = 25.0 - 2.5 * std::log10(rec.flux);
        }
        records.push_back(rec);
    }
    return records;
}

// Whether any pixel of `stamp` (0-based field columns/rows) lies in `window` (FITS), pixel by
// pixel.
bool shares_a_pixel(const PixelWindow& stamp, const Tile& window) {
    for (long j = stamp.row0; j < stamp.row0 + stamp.ny; ++j)
        for (long i = stamp.column0; i < stamp.column0 + stamp.nx; ++i)
            if (i + 1 >= window.x0 && i + 1 <= window.x1 && j + 1 >= window.y0 && j + 1 <= window.y1)
                return true;
    return false;
}

std::string temp_file(const std::string& name, const std::string& text) {
    const std::string path = ::testing::TempDir() + name;
    std::ofstream(path) << text;
    return path;
}

}  // namespace

// The window filter: a stamp reaches a window exactly when they share a pixel (pixel by
// pixel over random stamps and windows, overhanging the field's edges and touching corners).
TEST(Scene, StampReachesAWindowExactlyWhenTheyShareAPixel) {
    RandomStream r(3, 0, "stamps");
    long reached = 0;
    for (int k = 0; k < 20000; ++k) {
        const PixelWindow stamp{int(r.uniform(-12.0, 40.0)), int(r.uniform(-12.0, 40.0)),
                                1 + int(r.uniform(0.0, 12.0)), 1 + int(r.uniform(0.0, 12.0))};
        const long x0 = 1 + long(r.uniform(0.0, 25.0)), y0 = 1 + long(r.uniform(0.0, 25.0));
        const Tile window{x0, y0, x0 + long(r.uniform(0.0, 10.0)), y0 + long(r.uniform(0.0, 10.0))};
        const bool expect = shares_a_pixel(stamp, window);
        ASSERT_EQ(stamp_reaches(stamp, window), expect)
            << "stamp " << stamp.column0 << "," << stamp.row0 << " " << stamp.nx << "x" << stamp.ny
            << " window " << window.x0 << "," << window.y0 << "-" << window.x1 << "," << window.y1;
        reached += expect;
    }
    EXPECT_GT(reached, 500);  // both outcomes exercised (920 of 20000 here)
    EXPECT_LT(reached, 19000);
}

// prepare_scene keeps exactly the drawn objects whose stamps share a pixel with the window,
// in input order, each knowing its record.
TEST(Scene, PrepareSceneKeepsTheObjectsReachingTheWindow) {
    SceneOptions o;
    o.noise_rms = 0.05;
    SceneKernels k;
    k.galaxy = k.star = to_cartesian(psf_model());
    const std::vector<ObjectRecord> records = crowded_records();
    const Tile window{61, 41, 140, 90};
    const std::vector<PreparedObject> kept = prepare_scene(records, 0.04, k, o, window);
    std::vector<std::size_t> expect;
    for (std::size_t i = 0; i < records.size(); ++i) {
        const PreparedObject p = prepare_object(records[i], 0.04, k, o);
        if (p.drawn && shares_a_pixel(p.window, window)) expect.push_back(i);
    }
    ASSERT_EQ(kept.size(), expect.size());
    EXPECT_GT(kept.size(), 5u);
    EXPECT_LT(kept.size(), records.size());
    for (std::size_t n = 0; n < kept.size(); ++n) {
        EXPECT_EQ(kept[n].index, expect[n]);
        EXPECT_EQ(kept[n].id, records[expect[n]].id);
    }
}

// The kernels: stars as the PSF; galaxies through the PSF, through nothing when the models
// hold this very PSF, else through the difference kernel of the requested order.
TEST(Scene, KernelsFollowThePsfTheModelsHold) {
    ShapeletModel old_psf(0.0, 0.0, 1.0, 2), psf(0.0, 0.0, 1.6, 2);
    old_psf.at(0, 0) = 1.0 / (2.0 * std::sqrt(M_PI) * 1.0);
    psf.at(0, 0) = 1.0 / (2.0 * std::sqrt(M_PI) * 1.6);
    psf.at(2, 0) = 0.01;
    const SceneKernels plain = scene_kernels(psf);
    ASSERT_TRUE(plain.star && plain.galaxy);
    EXPECT_TRUE((plain.star->b.array() == to_cartesian(psf).b.array()).all());
    EXPECT_TRUE((plain.galaxy->b.array() == plain.star->b.array()).all());
    EXPECT_EQ(plain.galaxy_note, "the PSF");

    const SceneKernels same = scene_kernels(psf, psf, 4);
    EXPECT_TRUE(same.star);
    EXPECT_FALSE(same.galaxy);
    EXPECT_EQ(same.galaxy_note, "none (the models hold this PSF)");

    const SceneKernels diff = scene_kernels(psf, old_psf, 6);
    const DifferenceKernel expect = difference_kernel(old_psf, psf, 6);
    ASSERT_TRUE(diff.galaxy);
    EXPECT_EQ(diff.galaxy->n_max, 6);
    EXPECT_TRUE((diff.galaxy->b.array() == to_cartesian(expect.kernel).b.array()).all());
    EXPECT_EQ(diff.galaxy_note, "difference kernel (relative residual " +
                                    std::to_string(expect.report.relative_residual) + ")");
    EXPECT_EQ(scene_kernels(psf, old_psf).galaxy->n_max, psf.n_max);  // the PSF's order
    EXPECT_FALSE(read_scene_kernels("", "", 0.04, -1).star);
    EXPECT_EQ(read_scene_kernels("", "", 0.04, -1).galaxy_note, "none");
}

// The measured sky's noise sets the rms, F (never below 1) and the kernel of its correlation.
TEST(Scene, SkyNoiseSetsRmsFactorAndKernel) {
    NoiseRecord noise;
    noise.rms = 0.3;
    noise.noise_correlation = 0.9;
    noise.correlation.radius = 1;
    noise.correlation.values = {0.0, 0.1, 0.0, 0.2, 1.0, 0.2, 0.0, 0.1, 0.0};
    SceneOptions o;
    use_sky_noise(o, noise);
    EXPECT_EQ(o.noise_rms, 0.3);
    EXPECT_EQ(o.noise_correlation, 1.0);
    ASSERT_TRUE(o.noise_kernel);
    const NoiseKernel expect = correlated_noise_kernel(noise.correlation);
    EXPECT_EQ(o.noise_kernel->radius, expect.radius);
    EXPECT_EQ(o.noise_kernel->columns, expect.columns);
    noise.noise_correlation = 1.7;
    use_sky_noise(o, noise);
    EXPECT_EQ(o.noise_correlation, 1.7);
}

// A weight map of another size than the field is refused naming the file; one of the field's
// size gives noise_scale_from_weight's map.
TEST(Scene, NoiseScaleReadsAWeightMapOfTheFieldsSize) {
    const std::string path = ::testing::TempDir() + "scene-weight.fits";
    ImageArray weight = ImageArray::Constant(4, 6, 4.0);
    weight(1, 2) = 1.0;
    FitsWriter out(path, "test");
    out.write_image(weight, {"SCI", -64, "", {}, {}, {}});
    out.commit();
    const ImageArray scale = read_noise_scale(path, 6, 4);
    EXPECT_TRUE((scale == noise_scale_from_weight(weight)).all());
    try {
        read_noise_scale(path, 4, 6);
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        EXPECT_EQ(e.file(), path);
        EXPECT_EQ(e.message(), "the weight map is 6 x 4 pixels, the field 4 x 6");
    }
}

// Objects read and placed: x, y from ra, dec through the WCS, a band's coefficients and flux
// when asked, and a star without a PSF refused at its line.
TEST(Scene, ReadObjectsPlacesThemThroughTheWcs) {
    const Wcs wcs = tan_wcs(189.2, 62.2, 0.04, 50.5, 40.5, 15.0);
    ShapeletModel m(0.0, 0.0, 2.0, 2);
    m.coeffs[0] = 3.0;
    ObjectRecord g = galaxy_record(m, 0.0, 0.0, "g1");
    g.x.reset();
    g.y.reset();
    const SkyPosition sky = wcs.pixel_to_sky(12.25, 30.5);
    g.ra = sky.ra;
    g.dec = sky.dec;
    BandCoefficients a{"a", m.coeffs, g.flux, std::nullopt, std::nullopt, std::nullopt, Json::object()};
    BandCoefficients b = a;
    b.band = "b";
    for (auto& c : b.coeffs) c *= 0.5;
    b.flux = 0.5 * g.flux;
    g.bands = {a, b};
    // Provenance a render never reads (parent, flags, rotation, parents) is dropped as the
    // records are read; what it reads (frame, psf_beta, ring) stays.
    g.parent = "p7";
    g.flags = {"edge"};
    g.extra["rotation"] = 12.5;
    g.extra["parents"] = Json::array({"p7", "p9"});
    g.extra["frame"] = "intrinsic";
    g.extra["psf_beta"] = 0.05;
    g.extra["ring"] = Json::object({{"id", "g1"}, {"x", 1.0}, {"y", 2.0}});
    ObjectRecord star;
    star.id = "s1";
    star.kind = "star";
    star.ra = 189.2;
    star.dec = 62.2;
    star.flux = 4.0;
    const std::string path = temp_file("scene-objects.jsonl", g.to_json().dump() + "\n\n" +
                                                                  star.to_json().dump() + "\n");
    ObjectPlacement with_psf;
    with_psf.have_psf = true;
    const ObjectPlacement without_psf;
    const std::vector<ObjectRecord> records = read_objects(path, wcs, "", with_psf, 2);
    ASSERT_EQ(records.size(), 2u);
    const PixelPosition p = wcs.sky_to_pixel(g.ra, g.dec);
    EXPECT_EQ(*records[0].x, p.x);
    EXPECT_EQ(*records[0].y, p.y);
    EXPECT_NEAR(*records[0].x, 12.25, 1e-9);
    EXPECT_NEAR(*records[1].x, 50.5, 1e-9);
    EXPECT_NEAR(*records[1].y, 40.5, 1e-9);
    EXPECT_EQ(records[0].coeffs, g.coeffs);
    EXPECT_EQ(records[0].extra, Json({{"frame", "intrinsic"}, {"psf_beta", 0.05},
                                      {"ring", g.extra["ring"]}}));
    EXPECT_FALSE(records[0].parent);
    EXPECT_TRUE(records[0].flags.empty());

    // Band b: only the galaxy has bands, so the star's line is where it fails.
    try {
        read_objects(path, wcs, "b", with_psf, 1);
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        EXPECT_EQ(e.file(), path);
        EXPECT_EQ(e.line(), 3);
        EXPECT_EQ(e.field(), "bands");
    }
    const std::string galaxy_only = temp_file("scene-galaxy.jsonl", g.to_json().dump() + "\n");
    const ObjectRecord in_b = read_objects(galaxy_only, wcs, "b", without_psf, 1).at(0);
    EXPECT_EQ(in_b.flux, 0.5 * g.flux);
    EXPECT_EQ(in_b.coeffs, b.coeffs);
    try {
        read_objects(path, wcs, "", without_psf, 1);
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        EXPECT_EQ(e.line(), 3);
        EXPECT_EQ(e.field(), "kind");
        EXPECT_EQ(e.message(), "object s1 is a point source: give --psf");
    }
}

// The field given once: an object whose own x, y (the field sample drew it for) are not where
// its ra, dec fall on this WCS is refused at its line, unless placed by the sky; within
// 0.01 pixel it is the same field. An observed-frame galaxy through a PSF without the PSF it
// holds (--galaxy-psf) is refused: it would be convolved twice.
TEST(Scene, ReadObjectsRefusesAnotherFieldAndASecondConvolution) {
    const Wcs wcs = tan_wcs(189.2, 62.2, 0.04, 50.5, 40.5, 15.0);
    ShapeletModel m(0.0, 0.0, 2.0, 2);
    m.coeffs[0] = 3.0;
    ObjectRecord g = galaxy_record(m, 0.0, 0.0, "g1");
    const SkyPosition sky = wcs.pixel_to_sky(12.25, 30.5);
    g.ra = sky.ra;
    g.dec = sky.dec;
    g.x = 12.25 + 0.004;
    g.y = 30.5;
    ObjectRecord shifted = g;
    shifted.id = "g2";
    shifted.x = 22.25;  // drawn for a field 10 pixels along
    const std::string same = temp_file("scene-same.jsonl", g.to_json().dump() + "\n");
    const std::string other = temp_file("scene-other.jsonl", g.to_json().dump() + "\n" +
                                                                 shifted.to_json().dump() + "\n");
    const ObjectPlacement plain;
    EXPECT_NEAR(*read_objects(same, wcs, "", plain, 1).at(0).x, 12.25, 1e-9);
    try {
        read_objects(other, wcs, "", plain, 1);
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        EXPECT_EQ(e.line(), 2);
        EXPECT_EQ(e.field(), "x");
        EXPECT_NE(e.message().find("object g2 was drawn for another field"), std::string::npos)
            << e.message();
    }
    ObjectPlacement by_sky;
    by_sky.by_sky = true;
    EXPECT_NEAR(*read_objects(other, wcs, "", by_sky, 1).at(1).x, 12.25, 1e-9);

    ObjectRecord observed = g;
    observed.extra["frame"] = "observed";
    const std::string path = temp_file("scene-observed.jsonl", observed.to_json().dump() + "\n");
    ObjectPlacement psf_only;
    psf_only.have_psf = true;
    try {
        read_objects(path, wcs, "", psf_only, 1);
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        EXPECT_EQ(e.field(), "frame");
        EXPECT_NE(e.message().find("observed-frame model"), std::string::npos) << e.message();
    }
    ObjectPlacement both = psf_only;
    both.galaxy_psf_known = true;
    EXPECT_EQ(read_objects(path, wcs, "", both, 1).size(), 1u);
    EXPECT_EQ(read_objects(path, wcs, "", plain, 1).size(), 1u);  // no PSF: drawn as it is
}

// Drawn in strips, a window gives render_field's image bit for bit, with photon noise and a
// correlated background, on 1 and 3 threads, for strips of 1, 7 and 64 rows and one strip of
// the whole window (the stamps cut by a strip's edge are drawn in each strip they reach), and
// the same clipped light; the strips arrive in order, each once.
TEST(Scene, StripsGiveTheWholeWindow) {
    SceneOptions o;
    o.noise_rms = 0.05;
    o.noise_correlation = 1.84;
    o.gain = 40.0;
    o.seed = 9;
    o.clip_negative = true;
    const SceneKernels k = psf_kernels();
    const std::vector<ObjectRecord> records = crowded_records();
    const FieldGeometry field = crowded_field();
    const Tile window{11, 6, 190, 150};
    const RenderedScene whole = render_field(records, field, k, o, window, "x.jsonl");
    long with_holes = 0;
    for (const ClippedLight& c : whole.clipped) with_holes += c.flux > 0.0;
    EXPECT_GT(with_holes, 0);
    for (const int threads : {1, 3})
        for (const long rows : {1L, 7L, 64L, 145L}) {
            SceneOptions t = o;
            t.threads = threads;
            RenderedScene scene = prepare_field(records, field, k, t, window, "x.jsonl");
            ImageArray image = ImageArray::Constant(145, 180, -1.0);
            long next = 0;
            draw_in_strips(scene, t, rows, [&](long first, const ImageArray& strip) {
                EXPECT_EQ(first, next);
                EXPECT_EQ(strip.cols(), 180);
                image.block(first, 0, strip.rows(), 180) = strip;
                next = first + strip.rows();
            });
            EXPECT_EQ(next, 145);
            EXPECT_TRUE((image == whole.image).all()) << threads << " threads, " << rows << " rows";
            EXPECT_EQ(scene.image.size(), 0);
            for (std::size_t i = 0; i < whole.clipped.size(); ++i) {
                EXPECT_EQ(scene.clipped[i].flux, whole.clipped[i].flux) << i;
                EXPECT_EQ(scene.clipped[i].deepest, whole.clipped[i].deepest) << i;
            }
        }
    // A sink that fails stops the drawing; its error reaches the caller.
    RenderedScene scene = prepare_field(records, field, k, o, window, "x.jsonl");
    long calls = 0;
    EXPECT_THROW(draw_in_strips(scene, o, 10,
                                [&](long, const ImageArray&) {
                                    if (++calls == 3) throw Error("disk full");
                                }),
                 Error);
    EXPECT_EQ(calls, 3);
}

// A rendered field is prepare_scene + paint + add_noise; its truths are the objects centred in
// the window, so a grid of tiles lists every drawn object once, with the flux drawn (clipped
// light added back), the mag moved by it and the galaxies' intrinsic shape.
TEST(Scene, TruthListsEachObjectOnceAcrossTiles) {
    SceneOptions o;
    o.noise_rms = 0.05;
    o.seed = 4;
    o.clip_negative = true;
    const SceneKernels k = psf_kernels();
    const std::vector<ObjectRecord> records = crowded_records();
    const FieldGeometry field = crowded_field();
    const RenderedScene whole = render_field(records, field, k, o, Tile{1, 1, 200, 150}, "x.jsonl");
    ImageArray expect = paint(whole.objects, whole.window, o);
    add_noise(expect, whole.window, 200, o);
    EXPECT_TRUE((whole.image == expect).all());
    std::map<std::string, int> listed;
    for (const Tile& t : tile_grid(200, 150, 64, 64)) {
        const RenderedScene tile = render_field(records, field, k, o, t, "x.jsonl");
        for (const TruthRecord& truth : truth_records(tile, records)) {
            ++listed[truth.id];
            EXPECT_TRUE(t.owns(truth.x, truth.y)) << truth.id;
        }
    }
    const std::vector<TruthRecord> truths = truth_records(whole, records);
    long clipped = 0;
    for (std::size_t i = 0; i < whole.objects.size(); ++i) {
        const PreparedObject& p = whole.objects[i];
        if (!whole.window.owns(p.model.x, p.model.y)) continue;
        EXPECT_EQ(listed[p.id], 1) << p.id;
        const TruthRecord t = truth_record(p, records[p.index], whole.clipped[i]);
        EXPECT_EQ(t.flux, p.flux + whole.clipped[i].flux);
        EXPECT_EQ(t.clipped_flux.has_value(), whole.clipped[i].flux > 0.0);
        clipped += t.clipped_flux.has_value();
        EXPECT_EQ(t.shape.has_value(), p.kind == "galaxy");
        const ObjectRecord& r = records[p.index];
        if (r.mag) {
            EXPECT_NEAR(*t.mag, *r.mag - 2.5 * std::log10(t.flux / r.flux), 1e-12);
        }
    }
    EXPECT_EQ(long(truths.size()), long(listed.size()));
    // Written as JSON lines, one per truth, in that order.
    std::ostringstream written;
    write_truth_records(written, "t.jsonl", whole, records);
    std::istringstream lines(written.str());
    std::size_t n = 0;
    for (std::string line; std::getline(lines, line); ++n) {
        ASSERT_LT(n, truths.size());
        EXPECT_EQ(Json::parse(line), truths[n].to_json()) << line;
    }
    EXPECT_EQ(n, truths.size());
    EXPECT_GT(clipped, 0);
    // The summary: every drawn galaxy that lost light, listed or not.
    const ClippedSummary summary = summarise_clipped(whole);
    long lost = 0;
    double largest = 0.0, deepest = 0.0;
    for (std::size_t i = 0; i < whole.objects.size(); ++i) {
        if (!(whole.clipped[i].flux > 0.0)) continue;
        ++lost;
        largest = std::max(largest, whole.clipped[i].flux / std::abs(whole.objects[i].flux));
        deepest = std::min(deepest, whole.clipped[i].deepest);
    }
    EXPECT_GE(lost, clipped);
    EXPECT_EQ(summary.galaxies, lost);
    EXPECT_EQ(summary.largest, largest);
    EXPECT_EQ(summary.deepest, deepest);
    EXPECT_LT(summary.deepest, 0.0);

    // An object's failure names the records' file.
    SceneKernels none;
    try {
        render_field(records, field, none, o, Tile{1, 1, 200, 150}, "x.jsonl");
        ADD_FAILURE() << "no error";
    } catch (const Error& e) {
        EXPECT_EQ(e.file(), "x.jsonl");
        EXPECT_EQ(e.message().rfind("object s6: ", 0), 0u) << e.message();
    }
}

// A galaxy whose second moments are not positive has no e1, e2, rms_radius (null), but its
// lensing error; a star has no shape.
TEST(Scene, TruthOfUndefinedShapesIsNull) {
    PreparedObject p;
    p.id = "g";
    p.kind = "galaxy";
    p.flux = 2.0;
    p.intrinsic = ShapeSummary{};
    p.intrinsic->epsilon = Complex(std::nan(""), 0.1);
    p.intrinsic->rms_radius = std::nan("");
    p.lensing_error = 1e-9;
    ObjectRecord r;
    r.flux = 4.0;
    r.mag = 20.0;
    const TruthRecord t = truth_record(p, r, ClippedLight{});
    ASSERT_TRUE(t.shape);
    EXPECT_FALSE(t.shape->e1);
    EXPECT_EQ(t.shape->e2, 0.1);
    EXPECT_FALSE(t.shape->rms_radius);
    EXPECT_EQ(t.shape->lensing_error, 1e-9);
    EXPECT_DOUBLE_EQ(*t.mag, 20.0 + 2.5 * std::log10(2.0));
    EXPECT_FALSE(t.clipped_flux);
    p.intrinsic.reset();
    EXPECT_FALSE(truth_record(p, r, ClippedLight{}).shape);
}

// The objects' zero point: mag + 2.5 log₁₀ flux when all agree to 1e-6; none otherwise.
TEST(Scene, ObjectsZeroPointWhenTheyAgree) {
    std::vector<ObjectRecord> records(3);
    records[0].flux = 10.0;
    records[0].mag = 22.08 - 2.5;
    records[1].flux = 100.0;
    records[1].mag = 22.08 - 5.0 + 4e-7;
    records[2].flux = -1.0;  // no positive flux: not counted
    records[2].mag = 30.0;
    ASSERT_TRUE(objects_zero_point(records));
    EXPECT_NEAR(*objects_zero_point(records), 22.08, 1e-12);
    records[1].mag = 22.08 - 5.0 + 2e-6;
    EXPECT_FALSE(objects_zero_point(records));
    EXPECT_FALSE(objects_zero_point({records[2]}));
    EXPECT_FALSE(objects_zero_point({}));
}

// The image HDU: SCI, the WCS moved to the window, the run's cards, MAGZERO to 1e-6 and BAND
// only when there is one.
TEST(Scene, ImageSpecCarriesTheWindowsWcsAndTheRunsCards) {
    RenderedScene scene;
    scene.field = make_field(1.0, 1.0, 0.05, 189.2, 62.2);
    scene.field.bunit = "ELECTRONS/S";
    scene.window = Tile{101, 51, 300, 200};
    SceneOptions o;
    o.noise_rms = 0.5;
    o.lensing = Lensing{0.1, -0.05, 0.2};
    SceneKernels k;
    k.galaxy_note = "the PSF";
    std::vector<ObjectRecord> records(1);
    records[0].flux = 10.0;
    records[0].mag = 25.12345678 - 2.5;
    const FitsImageSpec spec =
        scene_image_spec(scene, records, o, k, {7, "psf.jsonl", "white", "f814w", 0.0, ""}, -64);
    EXPECT_EQ(spec.extname, "SCI");
    EXPECT_EQ(spec.bitpix, -64);
    EXPECT_EQ(spec.bunit, "ELECTRONS/S");
    // An exposure time and a unit named by the caller (render --exposure/--exptime, --bunit).
    const FitsImageSpec named =
        scene_image_spec(scene, records, o, k, {7, "psf.jsonl", "white", "", 30.0, "adu"}, -32);
    EXPECT_EQ(named.bunit, "adu");
    bool exptime = false;
    for (const FitsKeyword& c : named.keywords)
        if (c.name == "EXPTIME") exptime = std::get<double>(c.value) == 30.0;
    EXPECT_TRUE(exptime);
    ASSERT_TRUE(spec.wcs);
    EXPECT_EQ(spec.wcs->keywords().crpix1, scene.field.wcs.keywords().crpix1 - 100.0);
    EXPECT_EQ(spec.wcs->keywords().crpix2, scene.field.wcs.keywords().crpix2 - 50.0);
    std::map<std::string, FitsKeyword> cards;
    for (const FitsKeyword& c : spec.keywords) cards.emplace(c.name, c);
    EXPECT_EQ(std::get<std::string>(cards.at("SEED").value), "7");
    EXPECT_EQ(std::get<double>(cards.at("NOISERMS").value), 0.5);
    EXPECT_EQ(std::get<double>(cards.at("G2").value), -0.05);
    EXPECT_EQ(std::get<std::string>(cards.at("GALKERN").value), "the PSF");
    EXPECT_EQ(std::get<long long>(cards.at("TILEX0").value), 101);
    EXPECT_EQ(std::get<long long>(cards.at("FIELDNX").value), scene.field.nx);
    EXPECT_EQ(std::get<std::string>(cards.at("BAND").value), "f814w");
    EXPECT_EQ(std::get<double>(cards.at("MAGZERO").value), 25.123457);
    EXPECT_EQ(std::get<double>(cards.at("PHOTZP").value), 25.123457);
    EXPECT_EQ(cards.count("EXPTIME"), 0u);
    EXPECT_EQ(spec.keywords.back().name, "PHOTZP");
    records[0].mag.reset();
    const FitsImageSpec plain = scene_image_spec(scene, records, o, k, {7, "none", "white", "", 0.0, ""}, -32);
    for (const FitsKeyword& c : plain.keywords) {
        EXPECT_NE(c.name, "BAND");
        EXPECT_NE(c.name, "MAGZERO");
        EXPECT_NE(c.name, "PHOTZP");
    }
}

// The lines shapesim-render says on stderr and the NOISEMOD label, word for word.
TEST(Scene, ReportTexts) {
    const ClippedSummary clipped{3, 0.25, -0.5};
    EXPECT_EQ(app::clipped_note(clipped, 0.0),
              "3 galaxies had negative model light, set to zero (at most 0.25 of a galaxy's "
              "flux; deepest pixel -0.5)");
    EXPECT_EQ(app::clipped_note(clipped, 0.25),
              "3 galaxies had negative model light, set to zero (at most 0.25 of a galaxy's "
              "flux; deepest pixel -0.5 = -2 sigma)");
    EXPECT_EQ(app::clipped_note(ClippedSummary{}, 1.0), "");

    RenderedScene scene;
    scene.prepare_seconds = 1.5;
    scene.paint_seconds = 2.0;
    scene.noise_seconds = 0.5;
    scene.sink_seconds = 0.125;
    SceneKernels kernels;
    kernels.galaxy_note = "the PSF";
    EXPECT_EQ(app::render_summary(scene, 4, Tile{11, 21, 210, 170}, kernels, 0.25),
              "0 of 4 objects drawn into 200 x 150 pixels; galaxy kernel: the PSF; read 0.25 s, "
              "prepare (lens, convolve) 1.5 s, paint 2 s, noise 0.5 s, write 0.125 s");

    EXPECT_EQ(app::noise_label("", false), "drizzle-like 3x3 (NOISECOR)");
    EXPECT_EQ(app::noise_label("", true), "drizzle-like 3x3 (NOISECOR), scaled by the weight map");
    EXPECT_EQ(app::noise_label("sky.jsonl", true), "sky.jsonl, scaled by the weight map");
}
