// noise.hpp: the sky's measured noise (rms, 2-D autocorrelation, pixel quantiles), the kernel
// that draws it, and the comparison of two skies; scene.hpp's add_noise with a wide kernel.
#include "shapesim/noise.hpp"

#include "shapesim/detect.hpp"
#include "shapesim/error.hpp"
#include "shapesim/scene.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <random>

using namespace shapesim;

namespace {

void report(const std::string& name, double value) {
    std::cout << "[ metric ] noise." << name << " = " << value << "\n";
}

// A Gaussian kernel of width `s` pixels, radius `r`, one separable term, Σk² = 1: its
// correlation is known exactly (NoiseKernel::correlation, a direct sum).
NoiseKernel gaussian_kernel(double s, int r) {
    std::vector<double> g;
    double norm = 0.0;
    for (int x = -r; x <= r; ++x) {
        g.push_back(std::exp(-0.5 * x * x / (s * s)));
        norm += g.back() * g.back();
    }
    for (double& v : g) v /= std::sqrt(norm);
    NoiseKernel k;
    k.radius = r;
    k.columns = {g};
    k.rows = {g};
    return k;
}

ImageArray drawn_noise(const NoiseKernel& kernel, double rms, long n, std::uint64_t seed) {
    SceneOptions o;
    o.noise_rms = rms;
    o.noise_kernel = kernel;
    o.seed = seed;
    ImageArray image = ImageArray::Zero(n, n);
    add_noise(image, Tile{1, 1, n, n}, n, o);
    return image;
}

// Nothing detected at 50σ: the whole image is sky.
DetectionResult as_sky(const ImageArray& image) {
    DetectionOptions o;
    o.detect_thresh = 50.0;
    return detect_sources(image, nullptr, o);
}

}  // namespace

// The kernel built from an exact correlation (Gaussian-smoothed white noise, σ = 1.5 px, and
// a tilted elliptical, non-separable one, each given to its full support) has that correlation back at every
// lag to 5e-3: the kernel is cut where it keeps all but (2e-3)² of Σk², and split into separable
// terms to 2e-3 in norm (each moves the correlation by ≲ 4e-3).
TEST(NoiseKernel, ReproducesAnExactCorrelation) {
    const NoiseCorrelation round = gaussian_kernel(1.5, 6).correlation(12);
    // A Gaussian 2.0 × 0.8 px tilted by 30°: not separable. One term per row of the dense
    // kernel: row t is δ_t ⊗ k(·, t).
    NoiseKernel tilted;
    tilted.radius = 6;
    const double c = std::cos(0.5236), sn = std::sin(0.5236);
    double n2 = 0.0;
    for (int y = -6; y <= 6; ++y) {
        std::vector<double> column(13, 0.0), row;
        column[std::size_t(y + 6)] = 1.0;
        for (int x = -6; x <= 6; ++x) {
            const double u = c * x + sn * y, v = -sn * x + c * y;
            row.push_back(std::exp(-0.5 * (u * u / 4.0 + v * v / 0.64)));
            n2 += row.back() * row.back();
        }
        tilted.columns.push_back(column);
        tilted.rows.push_back(row);
    }
    for (auto& r : tilted.rows)
        for (double& v : r) v /= std::sqrt(n2);
    const NoiseCorrelation elongated = tilted.correlation(12);
    for (const auto* xi : {&round, &elongated}) {
        const NoiseKernel k = correlated_noise_kernel(*xi);
        const NoiseCorrelation back = k.correlation(12);
        double worst = 0.0, sum2 = 0.0;
        for (std::size_t p = 0; p < xi->values.size(); ++p)
            worst = std::max(worst, std::abs(back.values[p] - xi->values[p]));
        for (double v : k.dense()) sum2 += v * v;
        report("kernel_max_correlation_error", worst);
        report("kernel_terms", double(k.columns.size()));
        EXPECT_LT(worst, 5e-3);
        EXPECT_NEAR(sum2, 1.0, 1e-12);
        EXPECT_LE(k.radius, 12);
    }
    // White: one term of radius 0.
    NoiseCorrelation white;
    white.radius = 3;
    white.values.assign(49, 0.0);
    white.values[24] = 1.0;
    const NoiseKernel w = correlated_noise_kernel(white);
    EXPECT_EQ(w.radius, 0);
    EXPECT_EQ(w.columns.size(), 1u);
}

// Round trip: noise drawn with a kernel and measured on a 512² sky has the kernel's rms (to
// 1.5%) and correlation (to 0.015 at every lag ≤ 3; the sampling error of 250 000 pixels is
// ≈ 0.005); white noise measures white.
TEST(SkyNoise, MeasuresWhatWasDrawn) {
    const NoiseKernel k = gaussian_kernel(1.2, 5);
    const NoiseCorrelation truth = k.correlation(4);
    const NoiseRecord m = measure_sky_noise(as_sky(drawn_noise(k, 2.0, 512, 5)), {4, 2, 4, 1000});
    double worst = 0.0;
    for (int dy = -3; dy <= 3; ++dy)
        for (int dx = -3; dx <= 3; ++dx)
            worst = std::max(worst, std::abs(m.correlation.at(dx, dy) - truth.at(dx, dy)));
    report("measured_rms_over_drawn", m.rms / 2.0);
    report("measured_correlation_max_error", worst);
    EXPECT_NEAR(m.rms, 2.0, 0.03);
    EXPECT_NEAR(m.mad_sigma, 2.0, 0.04);
    EXPECT_LT(worst, 0.015);
    EXPECT_EQ(m.correlation.at(0, 0), 1.0);
    EXPECT_EQ(m.correlation.at(2, -1), m.correlation.at(-2, 1));

    const NoiseRecord w =
        measure_sky_noise(as_sky(drawn_noise(drizzle_noise_kernel(1.0), 1.0, 512, 6)));
    EXPECT_NEAR(w.correlation.at(1, 0), 0.0, 0.01);
    EXPECT_NEAR(w.correlation.at(1, 1), 0.0, 0.01);
    EXPECT_NEAR(w.rms, 1.0, 0.01);
}

// Objects are masked (and `grow` pixels round them): a bright disc on white noise leaves the
// rms at σ and ξ(1, 0) at 0; a hot pixel (a cosmic ray) is clipped.
TEST(SkyNoise, MasksObjectsAndClipsHotPixels) {
    ImageArray image = drawn_noise(drizzle_noise_kernel(1.0), 1.0, 256, 7);
    for (int j = 0; j < 256; ++j)
        for (int i = 0; i < 256; ++i)
            image(j, i) += 200.0 * std::exp(-0.5 * (std::pow(i - 100.0, 2) + std::pow(j - 120.0, 2)) / 64.0);
    image(30, 30) += 1e4;
    DetectionOptions o;
    const DetectionResult field = detect_sources(image, nullptr, o);
    ASSERT_GE(field.objects.size(), 1u);
    const NoiseRecord m = measure_sky_noise(field);
    report("masked_rms", m.rms);
    EXPECT_NEAR(m.rms, 1.0, 0.03);
    EXPECT_NEAR(m.correlation.at(1, 0), 0.0, 0.02);
    EXPECT_LT(m.pixels, 256L * 256L);
    // Without the mask the disc's light would dominate.
    EXPECT_THROW(measure_sky_noise(field, {8, 200, 4, 1000}), Error);  // nothing left
}

// The record is written and read back unchanged; a wrong-sized correlation is refused,
// naming the field.
TEST(NoiseRecordTest, RoundTripAndErrors) {
    const NoiseRecord m = measure_sky_noise(as_sky(drawn_noise(gaussian_kernel(1.0, 3), 0.5, 128, 8)), {3, 2, 4, 50});
    const NoiseRecord back = NoiseRecord::from_json(m.to_json());
    EXPECT_EQ(back.rms, m.rms);
    EXPECT_EQ(back.correlation.values, m.correlation.values);
    EXPECT_EQ(back.quantiles, m.quantiles);
    EXPECT_EQ(back.quantile_pixels, m.quantile_pixels);
    Json bad = m.to_json();
    bad["correlation"].erase(bad["correlation"].begin());
    try {
        NoiseRecord::from_json(bad);
        FAIL() << "a short correlation was accepted";
    } catch (const Error& e) {
        EXPECT_EQ(e.field(), "correlation");
    }
    bad = m.to_json();
    bad["rms"] = -1.0;
    EXPECT_THROW(NoiseRecord::from_json(bad), Error);
}

// Two skies of the same noise agree (KS p > 0.01, rms ratio 1 ± 2%); a sky 10% noisier is told
// apart (p < 1e-3; 5% gives p ≈ 0.01 from 16 000 pixels); a sky with its own correlation differs by its lags.
TEST(SkyComparisonTest, TellsSkiesApart) {
    const NoiseKernel k = gaussian_kernel(1.0, 4);
    const NoiseRecord a = measure_sky_noise(as_sky(drawn_noise(k, 1.0, 512, 9)));
    const NoiseRecord b = measure_sky_noise(as_sky(drawn_noise(k, 1.0, 512, 10)));
    const NoiseRecord louder = measure_sky_noise(as_sky(drawn_noise(k, 1.10, 512, 11)));
    const NoiseRecord white = measure_sky_noise(as_sky(drawn_noise(drizzle_noise_kernel(1.0), 1.0, 512, 12)));
    const SkyComparison same = compare_sky(a, b), loud = compare_sky(a, louder),
                        other = compare_sky(a, white), self = compare_sky(a, a);
    report("same_ks_p", same.ks_p);
    report("louder_ks_p", loud.ks_p);
    EXPECT_GT(same.ks_p, 0.01);
    EXPECT_NEAR(same.rms_ratio, 1.0, 0.02);
    EXPECT_LT(same.max_difference, 0.02);
    EXPECT_LT(loud.ks_p, 1e-3);
    EXPECT_GT(other.max_difference, 0.3);
    EXPECT_EQ(self.ks_d, 0.0);
    EXPECT_EQ(self.ks_p, 1.0);
}

// add_noise with a wide kernel (radius 6, several terms: the margin stream reaches past the
// field's first rows and columns) is bit-identical across 1 and 3 threads and a 3×2 tiling,
// and the drizzle kernel given explicitly equals the one F gives.
TEST(SceneNoise, WideKernelIsTileAndThreadInvariant) {
    NoiseKernel k = correlated_noise_kernel(gaussian_kernel(2.0, 6).correlation(8));
    ASSERT_GE(k.radius, 5);
    SceneOptions o;
    o.noise_rms = 1.0;
    o.noise_kernel = k;
    o.seed = 31;
    const long nx = 120, ny = 90;
    ImageArray whole = ImageArray::Zero(ny, nx);
    add_noise(whole, Tile{1, 1, nx, ny}, nx, o);
    SceneOptions threaded = o;
    threaded.threads = 3;
    ImageArray again = ImageArray::Zero(ny, nx);
    add_noise(again, Tile{1, 1, nx, ny}, nx, threaded);
    EXPECT_TRUE((again == whole).all());
    for (int j = 0; j < 2; ++j)
        for (int i = 0; i < 3; ++i) {
            const Tile t{1 + 40 * i, 1 + 45 * j, 40 * (i + 1), 45 * (j + 1)};
            ImageArray tile = ImageArray::Zero(45, 40);
            add_noise(tile, t, nx, o);
            EXPECT_TRUE((tile == whole.block(45 * j, 40 * i, 45, 40)).all()) << i << "," << j;
        }
    SceneOptions by_factor, by_kernel;
    by_factor.noise_rms = by_kernel.noise_rms = 1.0;
    by_factor.noise_correlation = 1.84;
    by_kernel.noise_kernel = drizzle_noise_kernel(1.84);
    ImageArray f = ImageArray::Zero(40, 40), g = ImageArray::Zero(40, 40);
    add_noise(f, Tile{1, 1, 40, 40}, 40, by_factor);
    add_noise(g, Tile{1, 1, 40, 40}, 40, by_kernel);
    EXPECT_TRUE((f == g).all());
}

// Only objects of S/N ≥ mask_snr (4) are masked: correlated noise thresholded at 1.3σ yields
// hundreds of "objects", its own peaks, and masking them all would take the measured rms and
// correlation down (every masked peak takes its correlated surroundings with it): −12% and
// 0.065 here. Kept in, the noise measures within 2.5% and 0.025 of what was drawn (the few
// noise peaks reaching S/N 4 are still masked).
TEST(SkyNoise, FaintDetectionsStayInTheSky) {
    const NoiseKernel k = gaussian_kernel(1.5, 6);
    const NoiseCorrelation truth = k.correlation(4);
    const DetectionResult field = detect_sources(drawn_noise(k, 1.0, 512, 13), nullptr, DetectionOptions{});
    ASSERT_GT(field.objects.size(), 100u);  // the noise's own peaks
    SkyNoiseOptions all;
    all.radius = 4;
    all.mask_snr = 0.0;
    SkyNoiseOptions bright = all;
    bright.mask_snr = 4.0;
    const NoiseRecord masked_all = measure_sky_noise(field, all), kept = measure_sky_noise(field, bright);
    const auto worst = [&](const NoiseRecord& m) {
        double w = 0.0;
        for (int dy = -3; dy <= 3; ++dy)
            for (int dx = -3; dx <= 3; ++dx)
                w = std::max(w, std::abs(m.correlation.at(dx, dy) - truth.at(dx, dy)));
        return w;
    };
    report("noise_peaks_detected", double(field.objects.size()));
    report("rms_all_masked", masked_all.rms);
    report("rms_bright_masked", kept.rms);
    report("correlation_error_all_masked", worst(masked_all));
    report("correlation_error_bright_masked", worst(kept));
    EXPECT_NEAR(kept.rms, 1.0, 0.025);
    EXPECT_LT(worst(kept), 0.025);
    EXPECT_LT(masked_all.rms, 0.97);          // the bias the S/N limit removes
    EXPECT_GT(worst(masked_all), 0.03);
}

// noise_scale: σ follows 1/√w with ⟨s²⟩ = 1 (halves of weight 1 and 4: σ ratio 2, the mean
// variance kept); bad pixels get 1; tiles and threads stay bit-identical; a map with no
// positive weight is refused.
TEST(SceneNoise, WeightMapScalesTheBackground) {
    const long n = 200;
    ImageArray weight(n, n);
    for (long j = 0; j < n; ++j)
        for (long i = 0; i < n; ++i) weight(j, i) = j < n / 2 ? 1.0 : 4.0;
    weight(0, 0) = 0.0;
    const ImageArray scale = noise_scale_from_weight(weight);
    EXPECT_EQ(scale(0, 0), 1.0);
    EXPECT_NEAR(scale(10, 10) / scale(150, 10), 2.0, 1e-12);
    EXPECT_NEAR((scale * scale).sum() - 1.0 + scale(0, 0), double(n * n) - 1.0 + 1.0, 1e-6 * n * n);
    SceneOptions o;
    o.noise_rms = 1.0;
    o.noise_kernel = correlated_noise_kernel(gaussian_kernel(1.2, 5).correlation(6));
    o.noise_scale = scale;
    o.seed = 41;
    ImageArray whole = ImageArray::Zero(n, n);
    add_noise(whole, Tile{1, 1, n, n}, n, o);
    const double low = whole.topRows(n / 2).square().mean(), high = whole.bottomRows(n / 2).square().mean();
    report("weight_scaled_variance_ratio", low / high);
    EXPECT_NEAR(low / high, 4.0, 0.4);
    EXPECT_NEAR(0.5 * (low + high), 1.0, 0.08);
    SceneOptions threaded = o;
    threaded.threads = 3;
    ImageArray again = ImageArray::Zero(n, n);
    add_noise(again, Tile{1, 1, n, n}, n, threaded);
    EXPECT_TRUE((again == whole).all());
    ImageArray tile = ImageArray::Zero(60, 70);
    add_noise(tile, Tile{31, 81, 100, 140}, n, o);
    EXPECT_TRUE((tile == whole.block(80, 30, 60, 70)).all());
    EXPECT_THROW(noise_scale_from_weight(ImageArray::Zero(4, 4)), Error);
}

// The histogram comparison is of the noise about each sky's own median: the same noise offset
// by 0.1σ (a background subtracted differently) agrees, the offset reported to within 4σ of the
// two medians' own scatter (each of 128² decimated, nearly independent pixels: 1.2533/128 =
// 0.0098, so 0.055 for the difference); louder noise is still told apart.
TEST(SkyComparisonTest, ComparesTheNoiseAboutItsMedian) {
    const NoiseKernel k = gaussian_kernel(1.0, 4);
    const NoiseRecord a = measure_sky_noise(as_sky(drawn_noise(k, 1.0, 512, 9)));
    NoiseRecord b = measure_sky_noise(as_sky(drawn_noise(k, 1.0, 512, 10)));
    for (double& q : b.quantiles) q += 0.1;  // detection subtracts a constant: shift its record
    const SkyComparison c = compare_sky(a, b);
    report("offset_sky_ks_p", c.ks_p);
    EXPECT_NEAR(c.median_offset, 0.1, 0.055);
    EXPECT_GT(c.ks_p, 0.01);
    NoiseRecord louder = measure_sky_noise(as_sky(drawn_noise(k, 1.10, 512, 11)));
    for (double& q : louder.quantiles) q += 0.1;
    EXPECT_LT(compare_sky(a, louder).ks_p, 1e-3);
}

namespace {

double normal_cdf(double z) { return 0.5 * std::erfc(-z / std::sqrt(2.0)); }

// A split normal: σ = 1 below its mode 0, 1.5 above (skewed: a sky with faint light in it),
// its CDF, density, quantile (by bisection), and standardised form (about its median, over its
// standard deviation), which is what a measured marginal holds.
struct SplitNormal {
    double left = 1.0, right = 1.5;
    double cdf(double x) const {
        const double w = 2.0 / (left + right);
        return x < 0.0 ? w * left * normal_cdf(x / left) : 1.0 - w * right * normal_cdf(-x / right);
    }
    double density(double x) const {
        const double s = x < 0.0 ? left : right;
        return 2.0 / ((left + right) * std::sqrt(2.0 * M_PI)) * std::exp(-0.5 * x * x / (s * s));
    }
    double quantile(double p) const {
        double lo = -20.0, hi = 20.0;
        for (int k = 0; k < 200; ++k) (cdf(0.5 * (lo + hi)) < p ? lo : hi) = 0.5 * (lo + hi);
        return 0.5 * (lo + hi);
    }
    double sd() const {
        const double mean = std::sqrt(2.0 / M_PI) * (right - left);
        return std::sqrt((std::pow(left, 3) + std::pow(right, 3)) / (left + right) - mean * mean);
    }
    /// The standardised quantile at the standard normal level z.
    double standard(double z) const { return (quantile(normal_cdf(z)) - quantile(0.5)) / sd(); }
    /// Its sampling error from n independent pixels.
    double error(double z, double n) const {
        const double p = normal_cdf(z);
        return std::sqrt(p * (1.0 - p) / n) / density(quantile(p)) / sd();
    }
    SkyMarginal table(double z_max, double dz) const {
        SkyMarginal m;
        m.z0 = -z_max;
        m.dz = dz;
        const int n = int(std::lround(2.0 * z_max / dz));
        for (int k = 0; k <= n; ++k) m.values.push_back(standard(-z_max + k * dz));
        return m;
    }
};

}  // namespace

// The marginal measured on white split-normal noise (512², drawn here from std::mt19937_64 by
// its inverse CDF) is the distribution's standardised quantiles at every level |z| ≤ 3, each
// within 5 of its sampling errors; its levels reach as far as 20 pixels lie beyond (Φ(−3.75)
// × 512² = 23); a Gaussian sky measures T(z) = z.
TEST(SkyMarginalTest, MeasuresAKnownDistribution) {
    const SplitNormal split;
    const long n = 512;
    std::mt19937_64 engine(17);
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    ImageArray image(n, n);
    std::vector<double> table;  // the quantile function on a fine grid, interpolated
    for (int k = 0; k <= 20000; ++k) table.push_back(split.quantile(1e-6 + (1.0 - 2e-6) * k / 20000.0));
    for (long k = 0; k < n * n; ++k) {
        const double at = (uniform(engine) - 1e-6) / (1.0 - 2e-6) * 20000.0;
        const long i = std::clamp(long(at), 0L, 19999L);
        image.data()[k] = table[std::size_t(i)] + (at - double(i)) * (table[std::size_t(i + 1)] - table[std::size_t(i)]);
    }
    const NoiseRecord m = measure_sky_noise(as_sky(image));
    ASSERT_FALSE(m.marginal.empty());
    EXPECT_DOUBLE_EQ(m.marginal.z0, -3.75);
    EXPECT_DOUBLE_EQ(m.marginal.dz, 0.05);
    double worst = 0.0;
    for (int k = -60; k <= 60; ++k) {
        const double z = 0.05 * k;
        const double error = (m.marginal(z) - split.standard(z)) / split.error(z, double(n * n));
        worst = std::max(worst, std::abs(error));
    }
    report("split_normal_marginal_worst_error_in_sigma", worst);
    EXPECT_LT(worst, 5.0);
    // Skewed: the 99th percentile 1.23× as far out as the 1st.
    EXPECT_NEAR(m.marginal(2.326) / -m.marginal(-2.326), split.standard(2.326) / -split.standard(-2.326), 0.03);

    const NoiseRecord g = measure_sky_noise(as_sky(drawn_noise(drizzle_noise_kernel(1.0), 1.0, 512, 18)));
    for (double z : {-3.0, -2.0, -1.0, 1.0, 2.0, 3.0}) {
        const double p = normal_cdf(z);
        const double error = std::sqrt(p * (1.0 - p) / (512.0 * 512.0)) /
                             (std::exp(-0.5 * z * z) / std::sqrt(2.0 * M_PI));
        EXPECT_NEAR(g.marginal(z), z, 5.0 * error) << z;
    }
}

// T is linear between its levels and continues along the mean slope of its last ten steps; a
// record keeps it through JSON; a table not ascending, or with dz ≤ 0, is refused naming
// "marginal".
TEST(SkyMarginalTest, MapsBetweenAndBeyondItsLevels) {
    SkyMarginal m;
    m.z0 = -1.0;
    m.dz = 0.1;
    for (int k = 0; k <= 20; ++k) m.values.push_back(std::pow(-1.0 + 0.1 * k, 3) + (-1.0 + 0.1 * k));
    m.validate();
    EXPECT_DOUBLE_EQ(m(-1.0), -2.0);
    EXPECT_DOUBLE_EQ(m(1.0), 2.0);
    EXPECT_NEAR(m(0.25), 0.5 * (m.values[12] + m.values[13]), 1e-15);
    const double slope = (m.values[20] - m.values[10]) / 1.0;
    EXPECT_NEAR(m(1.5), 2.0 + 0.5 * slope, 1e-12);
    EXPECT_NEAR(m(-1.5), -2.0 - 0.5 * slope, 1e-12);

    NoiseRecord r = measure_sky_noise(as_sky(drawn_noise(gaussian_kernel(1.0, 3), 0.5, 256, 19)));
    ASSERT_FALSE(r.marginal.empty());
    const NoiseRecord back = NoiseRecord::from_json(r.to_json());
    EXPECT_EQ(back.marginal.values, r.marginal.values);
    EXPECT_EQ(back.marginal.z0, r.marginal.z0);
    for (const char* broken : {"dz", "values"}) {
        Json bad = r.to_json();
        if (std::string(broken) == "dz") bad["marginal"]["dz"] = 0.0;
        else std::swap(bad["marginal"]["values"][3], bad["marginal"]["values"][4]);
        try {
            NoiseRecord::from_json(bad);
            FAIL() << "a broken marginal (" << broken << ") was accepted";
        } catch (const Error& e) {
            EXPECT_EQ(e.field(), "marginal");
        }
    }
}

// Render maps each correlated deviate through the marginal: white noise drawn with the split
// normal's table measures that distribution back (5 sampling errors at |z| ≤ 3); through a
// correlated kernel the map keeps ξ within 0.01 of the Gaussian field's; tiles and threads
// give the same bits; an empty marginal is the Gaussian draw.
TEST(SceneNoise, MarginalShapesThePixels) {
    const SplitNormal split;
    const long n = 512;
    SceneOptions o;
    o.noise_rms = 1.0;
    o.noise_kernel = drizzle_noise_kernel(1.0);
    o.noise_marginal = split.table(4.0, 0.05);
    o.seed = 43;
    ImageArray image = ImageArray::Zero(n, n);
    add_noise(image, Tile{1, 1, n, n}, n, o);
    const NoiseRecord m = measure_sky_noise(as_sky(image));
    double worst = 0.0;
    for (int k = -60; k <= 60; ++k) {
        const double z = 0.05 * k;
        worst = std::max(worst, std::abs(m.marginal(z) - split.standard(z)) / split.error(z, double(n * n)));
    }
    report("rendered_marginal_worst_error_in_sigma", worst);
    EXPECT_LT(worst, 5.0);

    SceneOptions correlated = o;
    correlated.noise_kernel = correlated_noise_kernel(gaussian_kernel(1.2, 5).correlation(6));
    SceneOptions gaussian = correlated;
    gaussian.noise_marginal = SkyMarginal{};
    ImageArray a = ImageArray::Zero(n, n), b = ImageArray::Zero(n, n);
    add_noise(a, Tile{1, 1, n, n}, n, correlated);
    add_noise(b, Tile{1, 1, n, n}, n, gaussian);
    const NoiseRecord ma = measure_sky_noise(as_sky(a)), mb = measure_sky_noise(as_sky(b));
    double dxi = 0.0;
    for (int dy = -3; dy <= 3; ++dy)
        for (int dx = -3; dx <= 3; ++dx)
            dxi = std::max(dxi, std::abs(ma.correlation.at(dx, dy) - mb.correlation.at(dx, dy)));
    report("marginal_correlation_shift", dxi);
    EXPECT_LT(dxi, 0.01);
    EXPECT_TRUE(mb.marginal(2.326) < ma.marginal(2.326) - 0.2);  // the skewed tail is there

    SceneOptions threaded = correlated;
    threaded.threads = 3;
    ImageArray again = ImageArray::Zero(n, n);
    add_noise(again, Tile{1, 1, n, n}, n, threaded);
    EXPECT_TRUE((again == a).all());
    ImageArray tile = ImageArray::Zero(60, 70);
    add_noise(tile, Tile{31, 81, 100, 140}, n, correlated);
    EXPECT_TRUE((tile == a.block(80, 30, 60, 70)).all());
}

// A full well: with `saturation`, every pixel above it (sky and noise included) is set to it
// and every other pixel is the unsaturated image's, bit for bit; a noise-free image is never
// saturated; a negative level is refused.
TEST(SceneNoise, SaturationCapsEveryPixel) {
    const long n = 64;
    ImageArray light = ImageArray::Zero(n, n);
    for (long j = 0; j < n; ++j)
        for (long i = 0; i < n; ++i)
            light(j, i) = 5e4 * std::exp(-0.5 * (std::pow(i - 31.5, 2) + std::pow(j - 30.0, 2)) / 4.0);
    SceneOptions o;
    o.noise_rms = 10.0;
    o.gain = 2.0;
    o.sky = 1000.0;
    o.seed = 44;
    ImageArray free_image = light, capped = light;
    add_noise(free_image, Tile{1, 1, n, n}, n, o);
    o.saturation = 2e4;
    add_noise(capped, Tile{1, 1, n, n}, n, o);
    long saturated = 0;
    for (long k = 0; k < n * n; ++k) {
        if (free_image.data()[k] >= 2e4) {
            EXPECT_EQ(capped.data()[k], 2e4);
            ++saturated;
        } else {
            EXPECT_EQ(capped.data()[k], free_image.data()[k]);
        }
    }
    EXPECT_GT(saturated, 5);
    EXPECT_EQ(capped.maxCoeff(), 2e4);
    SceneOptions truth = o;
    truth.noise_free = true;
    ImageArray clean = light;
    add_noise(clean, Tile{1, 1, n, n}, n, truth);
    EXPECT_TRUE((clean == light).all());
    o.saturation = -1.0;
    EXPECT_THROW(o.validate(), Error);
}
