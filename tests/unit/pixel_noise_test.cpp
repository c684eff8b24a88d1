// pixel_noise.hpp: the white noise's distribution (moments, KS, tails, neighbours, keys) and
// tile invariance, and the correlated noise against a brute-force double-precision sum.
#include "shapesim/pixel_noise.hpp"

#include "shapesim/error.hpp"
#include "shapesim/rng.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <optional>

using namespace shapesim;
using test::ks_p_value;

namespace {

void report(const std::string& name, double value) {
    std::cout << "[ metric ] pixel_noise." << name << " = " << value << "\n";
}

double normal_cdf(double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); }

}  // namespace

// 4 194 304 deviates of a 2048² field: mean, variance and kurtosis within 5σ; KS against Φ;
// the fractions beyond 2, 3, 4 and 4.5σ within 5σ of the normal's; the correlation of
// horizontal, vertical and diagonal neighbours and of two seeds below 5/√N.
TEST(WhiteNoise, IsStandardNormalAndIndependent) {
    const long n = 2048;
    const WhiteNoise a(17), b(18);
    std::vector<float> field(std::size_t(n * n)), other(std::size_t(n * n));
    for (long r = 0; r < n; ++r) {
        a.row(r, 0, n, field.data() + r * n);
        b.row(r, 0, n, other.data() + r * n);
    }
    const double count = double(n * n);
    double m1 = 0, m2 = 0, m4 = 0;
    long beyond[4] = {0, 0, 0, 0};
    const double edges[4] = {2.0, 3.0, 4.0, 4.5};
    double right = 0, down = 0, diagonal = 0, seeds = 0;
    double largest = 0.0;
    for (long r = 0; r < n; ++r)
        for (long c = 0; c < n; ++c) {
            const double z = field[std::size_t(r * n + c)];
            m1 += z;
            m2 += z * z;
            m4 += z * z * z * z;
            largest = std::max(largest, std::abs(z));
            for (int e = 0; e < 4; ++e) beyond[e] += std::abs(z) > edges[e];
            if (c + 1 < n) right += z * field[std::size_t(r * n + c + 1)];
            if (r + 1 < n) down += z * field[std::size_t((r + 1) * n + c)];
            if (r + 1 < n && c + 1 < n) diagonal += z * field[std::size_t((r + 1) * n + c + 1)];
            seeds += z * other[std::size_t(r * n + c)];
        }
    EXPECT_NEAR(m1 / count, 0.0, 5.0 / std::sqrt(count));
    EXPECT_NEAR(m2 / count, 1.0, 5.0 * std::sqrt(2.0 / count));
    EXPECT_NEAR(m4 / count, 3.0, 5.0 * std::sqrt(96.0 / count));
    for (int e = 0; e < 4; ++e) {
        const double p = std::erfc(edges[e] / std::sqrt(2.0));
        EXPECT_NEAR(double(beyond[e]) / count, p, 5.0 * std::sqrt(p / count)) << edges[e];
    }
    const double bound = 5.0 / std::sqrt(count);
    EXPECT_LT(std::abs(right / count), bound);
    EXPECT_LT(std::abs(down / count), bound);
    EXPECT_LT(std::abs(diagonal / count), bound);
    EXPECT_LT(std::abs(seeds / count), bound);
    std::vector<double> sample(field.begin(), field.begin() + 400000);
    const double p = ks_p_value(sample, normal_cdf);
    report("ks_p", p);
    report("largest_sigma", largest);
    EXPECT_GT(p, 1e-3);
}

// The tail beyond R = 3.44 (the ziggurat's base layer, drawn by Ziggurat::finish): 2·10⁵
// deviates conditioned on |z| > R follow the normal tail to beyond 5σ (KS), and the tail
// reaches as far as it should (the largest of 2·10⁵ tail draws is ≈ 5.2σ; more than 4.9).
TEST(WhiteNoise, TailFollowsTheNormalBeyondR) {
    const double R = Ziggurat::instance().edge(1), tail = std::erfc(R / std::sqrt(2.0));
    std::vector<double> beyond;
    const WhiteNoise noise(5);
    std::vector<float> row(1 << 16);
    for (long r = 0; beyond.size() < 200000; ++r) {
        noise.row(r, -64, long(row.size()), row.data());
        for (const float z : row)
            if (std::abs(z) > R) beyond.push_back(std::abs(z));
    }
    const double p = ks_p_value(beyond, [&](double x) {
        return x <= R ? 0.0 : 1.0 - std::erfc(x / std::sqrt(2.0)) / tail;
    });
    const double largest = *std::max_element(beyond.begin(), beyond.end());
    report("tail_ks_p", p);
    report("tail_largest_sigma", largest);
    EXPECT_GT(p, 1e-3);
    EXPECT_GT(largest, 4.9);
}

// A pixel's deviate does not depend on the span asked for: rows drawn whole equal rows drawn
// in pieces of every length 1 … 13 from every start (SIMD groups and their tails), margins
// included; pixels outside the keyed range are refused.
TEST(WhiteNoise, IsAFunctionOfThePixel) {
    const WhiteNoise noise(99);
    const long width = 200;
    std::vector<float> whole(static_cast<std::size_t>(width)), piece(16);
    for (const long row : {-64L, -1L, 0L, 12345L}) {
        noise.row(row, -64, width, whole.data());
        for (long length = 1; length <= 13; ++length)
            for (long start = -64; start + length <= -64 + width; start += 7) {
                noise.row(row, start, length, piece.data());
                for (long i = 0; i < length; ++i)
                    ASSERT_EQ(piece[std::size_t(i)], whole[std::size_t(start + 64 + i)]) << row << " " << start;
            }
    }
    EXPECT_THROW(noise.row(-65, 0, 1, piece.data()), Error);
    EXPECT_THROW(noise.row(0, -65, 1, piece.data()), Error);
}

// White noise equals the documented per-pixel draw (pixel_noise.hpp): the pixel's Philox4x32
// word through the single-precision ziggurat and, where that does not decide, Ziggurat::finish
// from the pixel's own "white noise retry" stream, bit for bit. 64 rows of 4 096 hold ~7 000
// such pixels: wedges settled by their first word or the fresh one (in lanes), tails, and the
// rare ones that need more words (finished one at a time).
TEST(WhiteNoise, EqualsThePerPixelDraw) {
    static constexpr std::uint64_t seed = 0xfeedULL;
    constexpr std::uint64_t purpose = fnv1a_64("white noise");
    const Ziggurat& zig = Ziggurat::instance();
    const WhiteNoise noise(seed);
    const long width = 4096, first = -13;
    std::vector<float> row_out(static_cast<std::size_t>(width));
    long slow = 0, tails = 0, long_draws = 0;
    for (long row = 100; row < 164; ++row) {
        noise.row(row, first, width, row_out.data());
        for (long i = 0; i < width; ++i) {
            const std::uint64_t q = std::uint64_t(first + i + WhiteNoise::margin);
            std::uint32_t block[4];
            philox4x32_blocks(seed, std::uint32_t(q / 4), std::uint32_t(row + WhiteNoise::margin),
                              std::uint32_t(purpose), std::uint32_t(purpose >> 32), 1, block);
            const std::uint32_t w = block[q % 4];
            const int layer = int(w & 127);
            const float x = float(w >> 8) * float(zig.edge(layer) * 0x1.0p-24);
            float expect = (w & 128) ? -x : x;
            if (!(x < float(zig.edge(layer + 1)))) {
                RandomStream more(seed, (std::uint64_t(row + WhiteNoise::margin) << 32) + q,
                                  "white noise retry");
                const double z = zig.finish(layer, double(x), more);
                expect = float((w & 128) ? -z : z);
                ++slow;
                tails += layer == 0;
                long_draws += more.position() > 2;
            }
            ASSERT_EQ(row_out[std::size_t(i)], expect) << "row " << row << " pixel " << i;
        }
    }
    EXPECT_GT(slow, 5000);
    EXPECT_GT(tails, 50);
    EXPECT_GT(long_draws, 10);
}

// Correlated noise equals the direct double-precision sum Σ_d k(d) w(p + d) of the same white
// pixels to single precision, for a drizzle kernel and a measured-like wide one, row after row
// (the ring) and over a window that starts inside the field.
TEST(CorrelatedNoise, EqualsTheDirectSum) {
    NoiseCorrelation xi;
    xi.radius = 6;
    xi.values.assign(13 * 13, 0.0);
    for (int dy = -6; dy <= 6; ++dy)
        for (int dx = -6; dx <= 6; ++dx)
            xi.values[std::size_t((dy + 6) * 13 + dx + 6)] = std::exp(-(dx * dx + 1.5 * dy * dy + dx * dy) / 4.0);
    // F = 1 is white noise: one unit tap, the row returned as drawn.
    for (const NoiseKernel& kernel :
         {drizzle_noise_kernel(1.0), drizzle_noise_kernel(1.84), correlated_noise_kernel(xi)}) {
        const int K = kernel.radius, w = 2 * K + 1;
        const std::vector<double> k = kernel.dense();
        const long first = 37, nx = 53;
        CorrelatedNoise noise(kernel, 8, first, nx);
        const WhiteNoise white(8);
        std::vector<float> strip(std::size_t(nx + 2 * K));
        double worst = 0.0;
        for (long row = 3; row < 40; row += (row < 20 ? 1 : 9)) {
            const float* got = noise.row(row);
            std::vector<double> expect(std::size_t(nx), 0.0);
            for (int dy = -K; dy <= K; ++dy) {
                white.row(row + dy, first - K, nx + 2 * K, strip.data());
                for (int dx = -K; dx <= K; ++dx)
                    for (long i = 0; i < nx; ++i)
                        expect[std::size_t(i)] += k[std::size_t((dy + K) * w + dx + K)] * strip[std::size_t(i + K + dx)];
            }
            for (long i = 0; i < nx; ++i)
                worst = std::max(worst, std::abs(double(got[i]) - expect[std::size_t(i)]));
        }
        report("correlated_max_error_radius_" + std::to_string(K), worst);
        EXPECT_LT(worst, 2e-5) << K;
        EXPECT_THROW(noise.row(2), Error);
    }
}

// Photon noise equals the documented per-pixel draw: the pixel's Philox4x32 block, then its
// own RandomStream, through poisson_deviate, bit for bit. Means from 1e-3 to 1e7 photons,
// across the inversion/PTRS split at 10, with runs of bright pixels (whose blocks are drawn
// together, eight at a time with AVX2) broken by dark and negative pixels, and draws that go
// on into their own stream (its first block's trials in lanes) and beyond its first block.
TEST(PhotonNoise, EqualsThePerPixelDraw) {
    static constexpr std::uint64_t seed = 0x5eed5eedULL;
    constexpr std::uint64_t purpose = fnv1a_64("photon noise");
    struct Source {
        const std::uint32_t* block;
        std::uint64_t pixel;
        int used = 0;
        std::optional<RandomStream> more;
        std::uint64_t next() {
            if (used < 2) {
                const std::uint64_t w = block[2 * used] | (std::uint64_t(block[2 * used + 1]) << 32);
                ++used;
                return w;
            }
            if (!more) more.emplace(seed, pixel, "photon noise more");
            return more->next_u64();
        }
        double uniform() { return double(next() >> 11) * 0x1.0p-53; }
        double uniform_open() { return (double(next() >> 11) + 0.5) * 0x1.0p-53; }
    };
    const PhotonNoise photon(seed);
    const double gain = 4.0, least = 1e-3;
    const long width = 3001, first = 17;
    std::vector<double> pixels(static_cast<std::size_t>(width)), expect(pixels.size());
    long drawn = 0, fallback = 0, deep = 0;
    for (const long row : {0L, 5L, 123456L, 7L, 8L, 9L, 10L}) {
        RandomStream pick(seed, std::uint64_t(row), "test signal");
        for (long i = 0; i < width; ++i) {
            const double s = i % 11 == 3 ? 0.0 : std::pow(10.0, pick.uniform(-3.0, 7.0)) / gain;
            pixels[std::size_t(i)] = i % 29 == 0 ? -s : s;  // a few negative: left alone
        }
        for (long i = 0; i < width; ++i) {
            const double s = pixels[std::size_t(i)];
            expect[std::size_t(i)] = s;
            if (!(s > 0.0 && s >= least)) continue;
            std::uint32_t block[4];
            const std::uint32_t column = std::uint32_t(first + i + WhiteNoise::margin);
            philox4x32_blocks(seed, column, std::uint32_t(row + WhiteNoise::margin),
                              std::uint32_t(purpose), std::uint32_t(purpose >> 32), 1, block);
            Source source{block, (std::uint64_t(row + WhiteNoise::margin) << 32) + column, 0, std::nullopt};
            expect[std::size_t(i)] = double(poisson_deviate(s * gain, source)) / gain;
            ++drawn;
            fallback += source.used > 2 || (s * gain >= 10.0 && source.more.has_value());
            deep += source.more.has_value() && source.more->position() > 4;
        }
        photon.row(row, first, width, gain, least, pixels.data());
        for (long i = 0; i < width; ++i)
            ASSERT_EQ(pixels[std::size_t(i)], expect[std::size_t(i)]) << "row " << row << " pixel " << i;
    }
    EXPECT_GT(drawn, 6000);
    EXPECT_GT(fallback, 10);  // draws that needed more than their block's two words
    EXPECT_GT(deep, 0);       // and more than their stream's first block
    std::cout << "[ metric ] pixel_noise.photon_deep_draws = " << deep << "\n";
    EXPECT_THROW(photon.row(0, 0, 1, gain, least, std::vector<double>{1e300}.data()), Error);
}
