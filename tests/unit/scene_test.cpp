// Painting scenes (scene.hpp): exactness against brute force, flux, truncation, tiles and
// threads bit for bit, noise statistics, shear recovery.
#include "shapesim/scene.hpp"

#include "shapesim/basis1d.hpp"
#include "shapesim/error.hpp"
#include "shapesim/polar.hpp"
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
