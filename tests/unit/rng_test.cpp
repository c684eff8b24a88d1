// Counter-based random streams (share/shapesim/rng.hpp): Random123's known answers, the fixed
// key layout and FNV-1a, reproducibility (same key ⇒ same numbers, in any order or thread),
// pinned first values (bit-identical across builds), and each distribution against its exact
// law (moments within sampling error, chi-square on the Poisson pmf, Kolmogorov–Smirnov on the
// continuous CDFs). Fixed seeds make every statistical test deterministic; the thresholds
// (p > 0.001, 5σ) say how unlucky a correct generator would have to be to fail on first writing.
#include "shapesim/rng.hpp"

#include "shapesim/error.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <thread>
#include <vector>

using namespace shapesim;
using test::ks_p_value;

namespace {

constexpr std::uint64_t kSeed = 20250611;

// Regularised upper incomplete gamma Q(a, x): series below a + 1, continued fraction above.
double gamma_q(double a, double x) {
    const double log_prefactor = -x + a * std::log(x) - std::lgamma(a);
    if (x < a + 1.0) {
        double term = 1.0 / a, sum = term;
        for (int k = 1; k < 1000 && term > 1e-17 * sum; ++k) sum += (term *= x / (a + k));
        return 1.0 - sum * std::exp(log_prefactor);
    }
    const double tiny = 1e-300;  // modified Lentz
    double b = x + 1.0 - a, c = 1.0 / tiny, d = 1.0 / b, h = d;
    for (int i = 1; i < 1000; ++i) {
        const double an = -i * (i - a);
        b += 2.0;
        d = an * d + b;
        d = std::abs(d) < tiny ? 1.0 / tiny : 1.0 / d;
        c = b + an / c;
        if (std::abs(c) < tiny) c = tiny;
        h *= d * c;
        if (std::abs(d * c - 1.0) < 1e-16) break;
    }
    return std::exp(log_prefactor) * h;
}

// Chi-square p-value of Poisson counts against the exact pmf. Cells k = 0, 1, … are merged
// left to right until each expects ≥ 5 draws; the remainder joins the last cell.
double poisson_chi_square_p(double mean, int draws, std::uint64_t id) {
    const int k_max = int(mean + 20.0 * std::sqrt(mean) + 20.0);  // pmf beyond: < 1e-30
    std::vector<double> observed(k_max + 1, 0.0), expected(k_max + 1);
    RandomStream s(kSeed, id, "poisson-chi2");
    for (int i = 0; i < draws; ++i) observed[std::min<std::uint64_t>(s.poisson(mean), k_max)] += 1;
    for (int k = 0; k <= k_max; ++k)
        expected[k] = draws * std::exp(-mean + k * std::log(mean) - std::lgamma(k + 1.0));
    std::vector<double> cell_observed, cell_expected;
    double o = 0.0, e = 0.0;
    for (int k = 0; k <= k_max; ++k) {
        o += observed[k];
        e += expected[k];
        if (e >= 5.0) {
            cell_observed.push_back(o);
            cell_expected.push_back(e);
            o = e = 0.0;
        }
    }
    cell_observed.back() += o;
    cell_expected.back() += e;
    double chi2 = 0.0;
    for (size_t c = 0; c < cell_observed.size(); ++c)
        chi2 += std::pow(cell_observed[c] - cell_expected[c], 2) / cell_expected[c];
    return gamma_q(0.5 * (double(cell_observed.size()) - 1.0), 0.5 * chi2);
}

}  // namespace

// Random123's known-answer vectors for Philox4x64-10 (kat_vectors of the distribution).
TEST(Rng, PhiloxKnownAnswers) {
    using B = std::array<std::uint64_t, 4>;
    EXPECT_EQ(philox_block({0, 0, 0, 0}, {0, 0}),
              (B{0x16554d9eca36314cULL, 0xdb20fe9d672d0fdcULL, 0xd7e772cee186176bULL,
                 0x7e68b68aec7ba23bULL}));
    const std::uint64_t ones = ~std::uint64_t(0);
    EXPECT_EQ(philox_block({ones, ones, ones, ones}, {ones, ones}),
              (B{0x87b092c3013fe90bULL, 0x438c3c67be8d0224ULL, 0x9cc7d7c69cd777b6ULL,
                 0xa09caebf594f0ba0ULL}));
    EXPECT_EQ(philox_block({0x243f6a8885a308d3ULL, 0x13198a2e03707344ULL, 0xa4093822299f31d0ULL,
                            0x082efa98ec4e6c89ULL},
                           {0x452821e638d01377ULL, 0xbe5466cf34e90c6cULL}),
              (B{0xa528f45403e61d95ULL, 0x38c72dbd566e9788ULL, 0xa5a1610e72fd18b5ULL,
                 0x57bd43b5e52b7fe6ULL}));
}

// FNV-1a 64 reference values (Fowler–Noll–Vo test suite) and the documented key layout.
TEST(Rng, HashAndKeyLayout) {
    EXPECT_EQ(fnv1a_64(""), 0xcbf29ce484222325ULL);
    EXPECT_EQ(fnv1a_64("a"), 0xaf63dc4c8601ec8cULL);
    EXPECT_EQ(fnv1a_64("foobar"), 0x85944171f73967e8ULL);
    static_assert(fnv1a_64("a") == 0xaf63dc4c8601ec8cULL, "constexpr");
    RandomStream s(kSeed, 42, "position");
    const auto block0 = philox_block({0, fnv1a_64("position"), 0, 0}, {kSeed, 42});
    const auto block1 = philox_block({1, fnv1a_64("position"), 0, 0}, {kSeed, 42});
    for (int i = 0; i < 4; ++i) EXPECT_EQ(s.next_u64(), block0[i]);
    for (int i = 0; i < 4; ++i) EXPECT_EQ(s.next_u64(), block1[i]);
    RandomStream by_name(kSeed, "M01", "noise"), by_hash(kSeed, fnv1a_64("M01"), "noise");
    EXPECT_EQ(by_name.next_u64(), by_hash.next_u64());
}

// Pinned first values: a change here changes every simulation (DESIGN: same inputs + same
// seed ⇒ bit-identical outputs). Uniform and Epanechnikov values are exact arithmetic on the
// words; Gaussian values also pass through libm's log/cos (glibc here).
TEST(Rng, PinnedFirstValues) {
    RandomStream s(kSeed, 42, "pin");
    EXPECT_EQ(s.next_u64(), 0x16721f433dfbda83ULL);
    EXPECT_EQ(s.next_u64(), 0xb97b2971d6a408d6ULL);
    EXPECT_EQ(s.next_u64(), 0x6299f1aa27e6ce5fULL);
    EXPECT_EQ(s.next_u64(), 0x929ae7a6b2ba4993ULL);
    EXPECT_EQ(s.uniform(), 0x1.8fbb976d99cacp-2);
    EXPECT_EQ(s.uniform(), 0x1.f28ee5d8b93p-9);
    EXPECT_EQ(s.uniform(), 0x1.c5e471b42d172p-2);
    RandomStream g(kSeed, "M01", "noise");
    EXPECT_EQ(g.gaussian(), 0x1.22eb5b61f0acdp+1);
    EXPECT_EQ(g.gaussian(), -0x1.00e02876139f4p-1);
    EXPECT_EQ(g.gaussian(), 0x1.d39f4a76538efp-1);
    RandomStream p(kSeed, "M01", "counts");
    EXPECT_EQ(p.poisson(0.5), 0u);
    EXPECT_EQ(p.poisson(3.2), 3u);
    EXPECT_EQ(p.poisson(30.0), 21u);
    EXPECT_EQ(p.poisson(1e4), 9816u);
    EXPECT_EQ(p.poisson(1e9), 999989148u);
    RandomStream e(kSeed, 7, "kernel");
    EXPECT_EQ(e.epanechnikov(), 0x1.68dda1c08a56p-2);
    EXPECT_EQ(e.epanechnikov(), 0x1.6289d53e4894cp-1);
    EXPECT_EQ(e.epanechnikov(), 0x1.79ae1cf686cap-4);
}

// Streams made from first_blocks' blocks give the streams' own numbers, into later blocks.
TEST(Rng, FirstBlocksStartTheStreams) {
    constexpr PurposeHash purpose("first blocks");
    const std::vector<std::uint64_t> ids = {0, 1, 42, 0xffffffffffffffffULL, 1ULL << 40};
    std::vector<std::array<std::uint64_t, 4>> blocks(ids.size());
    RandomStream::first_blocks(kSeed, ids.data(), ids.size(), purpose, blocks.data());
    for (std::size_t k = 0; k < ids.size(); ++k) {
        RandomStream alone(kSeed, ids[k], purpose), primed(kSeed, ids[k], purpose, blocks[k]);
        for (int w = 0; w < 9; ++w) ASSERT_EQ(primed.next_u64(), alone.next_u64()) << k << " " << w;
    }
}

// Same key ⇒ same sequence, whatever else is drawn in between or in which order streams are
// made; seek jumps to any word.
TEST(Rng, SameKeySameSequenceInAnyOrder) {
    RandomStream a(kSeed, 5, "x"), b(kSeed, 5, "x");
    std::vector<double> first;
    for (int i = 0; i < 50; ++i) first.push_back(a.gaussian());
    RandomStream other(kSeed, 6, "x");
    for (int i = 0; i < 50; ++i) {
        other.uniform();  // interleaved draws from another stream change nothing
        EXPECT_EQ(b.gaussian(), first[i]);
    }
    RandomStream c(kSeed, 5, "x");
    c.seek(37);
    RandomStream d(kSeed, 5, "x");
    for (int i = 0; i < 37; ++i) d.next_u64();
    EXPECT_EQ(d.position(), 37u);
    for (int i = 0; i < 9; ++i) EXPECT_EQ(c.next_u64(), d.next_u64());
}

// Streams made in worker threads, in a different order per thread, equal the serial ones.
TEST(Rng, ThreadIndependent) {
    const int objects = 64, draws = 20;
    auto realise = [&](int id) {
        RandomStream s(kSeed, std::uint64_t(id), "thread");
        std::vector<double> v;
        for (int i = 0; i < draws; ++i) v.push_back(s.uniform() + s.gaussian() + s.poisson(40.0));
        return v;
    };
    std::vector<std::vector<double>> serial(objects), parallel(objects);
    for (int id = 0; id < objects; ++id) serial[id] = realise(id);
    std::vector<std::thread> workers;
    for (int t = 0; t < 4; ++t)
        workers.emplace_back([&, t] {
            for (int k = objects - 1 - t; k >= 0; k -= 4) parallel[k] = realise(k);
        });
    for (auto& w : workers) w.join();
    EXPECT_EQ(serial, parallel);
}

// Changing any part of the key changes the numbers.
TEST(Rng, DifferentKeysDiffer) {
    const std::uint64_t base = RandomStream(kSeed, 1, "p").next_u64();
    EXPECT_NE(RandomStream(kSeed + 1, 1, "p").next_u64(), base);
    EXPECT_NE(RandomStream(kSeed, 2, "p").next_u64(), base);
    EXPECT_NE(RandomStream(kSeed, 1, "q").next_u64(), base);
    EXPECT_NE(RandomStream(kSeed, "1", "p").next_u64(), base);  // string "1" ≠ integer 1
    // Neighbouring ids share no words in their first blocks.
    std::vector<std::uint64_t> words;
    for (std::uint64_t id = 0; id < 100; ++id) {
        RandomStream s(kSeed, id, "p");
        for (int i = 0; i < 8; ++i) words.push_back(s.next_u64());
    }
    std::sort(words.begin(), words.end());
    EXPECT_EQ(std::adjacent_find(words.begin(), words.end()), words.end());
}

// Uniform: 53 bits (k · 2⁻⁵³, odd k occur), bounds, open variant, moments and KS.
TEST(Rng, Uniform) {
    RandomStream s(kSeed, 1, "uniform");
    const int n = 100000;
    std::vector<double> v(n);
    double sum = 0.0, sum2 = 0.0;
    bool odd_seen = false;
    for (double& x : v) {
        x = s.uniform();
        ASSERT_GE(x, 0.0);
        ASSERT_LT(x, 1.0);
        const double k = std::ldexp(x, 53);
        ASSERT_EQ(k, std::floor(k));
        odd_seen |= std::fmod(k, 2.0) == 1.0;
        sum += x;
        sum2 += x * x;
    }
    EXPECT_TRUE(odd_seen);
    EXPECT_NEAR(sum / n, 0.5, 5.0 * std::sqrt(1.0 / 12 / n));
    EXPECT_NEAR(sum2 / n - (sum / n) * (sum / n), 1.0 / 12, 5.0 * std::sqrt(1.0 / 180 / n));
    EXPECT_GT(ks_p_value(v, [](double x) { return x; }), 1e-3);
    RandomStream a(kSeed, 1, "uniform"), b(kSeed, 1, "uniform");
    for (int i = 0; i < 1000; ++i) {
        const double open = b.uniform_open();
        EXPECT_EQ(open, a.uniform() + 0x1.0p-54);
        EXPECT_GT(open, 0.0);
        EXPECT_LT(open, 1.0);
    }
    for (int i = 0; i < 1000; ++i) {
        const double x = a.uniform(-3.0, 5.0);
        EXPECT_GE(x, -3.0);
        EXPECT_LT(x, 5.0);
    }
}

// Gaussian: moments (mean 0, variance 1, kurtosis 3), pair uncorrelated, KS against Φ.
TEST(Rng, Gaussian) {
    RandomStream s(kSeed, 1, "gaussian");
    const int n = 100000;
    std::vector<double> v;
    double m1 = 0, m2 = 0, m4 = 0, cross = 0;
    for (int i = 0; i < n / 2; ++i) {
        const auto [z0, z1] = s.gaussian_pair();
        for (const double z : {z0, z1}) {
            v.push_back(z);
            m1 += z;
            m2 += z * z;
            m4 += z * z * z * z;
        }
        cross += z0 * z1;
    }
    EXPECT_NEAR(m1 / n, 0.0, 5.0 / std::sqrt(n));
    EXPECT_NEAR(m2 / n, 1.0, 5.0 * std::sqrt(2.0 / n));
    EXPECT_NEAR(m4 / n, 3.0, 5.0 * std::sqrt(96.0 / n));
    EXPECT_NEAR(cross / (n / 2), 0.0, 5.0 / std::sqrt(n / 2));
    EXPECT_GT(ks_p_value(v, [](double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); }), 1e-3);
    RandomStream a(kSeed, 2, "g"), b(kSeed, 2, "g");
    EXPECT_EQ(a.gaussian(3.0, 2.0), 3.0 + 2.0 * b.gaussian());
    EXPECT_EQ(a.position(), 2u);
}

// The ziggurat: one word per deviate from a stream, the rest from a second one. Moments, the
// tail fraction beyond R (2Φ(−R) = 5.7e-4), a KS test against Φ on 400 000 deviates, and the
// fraction of words that needed more (2.7% for 128 layers: 1 − mean of x_{i+1}/x_i).
TEST(Rng, ZigguratNormal) {
    const Ziggurat& zig = Ziggurat::instance();
    RandomStream words(kSeed, 3, "ziggurat"), more(kSeed, 4, "ziggurat more");
    const int n = 400000;
    std::vector<double> v;
    double m1 = 0, m2 = 0, m4 = 0;
    long slow = 0, tail = 0;
    for (int i = 0; i < n; ++i) {
        const double z = zig(words.next_u64(), [&]() -> RandomStream& {
            ++slow;
            return more;
        });
        v.push_back(z);
        m1 += z;
        m2 += z * z;
        m4 += z * z * z * z;
        if (std::abs(z) > 3.442619855899) ++tail;
    }
    EXPECT_NEAR(m1 / n, 0.0, 5.0 / std::sqrt(n));
    EXPECT_NEAR(m2 / n, 1.0, 5.0 * std::sqrt(2.0 / n));
    EXPECT_NEAR(m4 / n, 3.0, 5.0 * std::sqrt(96.0 / n));
    const double expect_tail = std::erfc(3.442619855899 / std::sqrt(2.0));
    EXPECT_NEAR(double(tail) / n, expect_tail, 5.0 * std::sqrt(expect_tail / n));
    EXPECT_NEAR(double(slow) / n, 0.027, 0.002);
    EXPECT_GT(ks_p_value(v, [](double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); }), 1e-3);
}

// Poisson: mean and variance within 5σ of μ for μ = 0.5, 5, 30, 1e4 (σ of the sample
// variance from μ₄ − σ⁴ = μ + 2μ²), μ = 0 ⇒ 0 with no word used, bad means rejected.
TEST(Rng, PoissonMoments) {
    for (const double mean : {0.5, 5.0, 30.0, 1e4}) {
        RandomStream s(kSeed, std::uint64_t(mean * 10), "poisson");
        const int n = 200000;
        double sum = 0.0, sum2 = 0.0;
        for (int i = 0; i < n; ++i) {
            const double k = double(s.poisson(mean));
            sum += k;
            sum2 += k * k;
        }
        const double m = sum / n, var = sum2 / n - m * m;
        EXPECT_NEAR(m, mean, 5.0 * std::sqrt(mean / n)) << mean;
        EXPECT_NEAR(var, mean, 5.0 * std::sqrt((mean + 2 * mean * mean) / n)) << mean;
    }
    RandomStream s(kSeed, 1, "p");
    EXPECT_EQ(s.poisson(0.0), 0u);
    EXPECT_EQ(s.position(), 0u);
    EXPECT_THROW(s.poisson(-1.0), Error);
    EXPECT_THROW(s.poisson(std::numeric_limits<double>::quiet_NaN()), Error);
    EXPECT_THROW(s.poisson(std::numeric_limits<double>::infinity()), Error);
}

// Poisson pmf against the exact law by chi-square: inversion (μ = 0.5, 5, 9.9) and PTRS
// (μ = 10, 30, 200), p > 0.001.
TEST(Rng, PoissonPmfChiSquare) {
    std::uint64_t id = 0;
    for (const double mean : {0.5, 5.0, 9.9, 10.0, 30.0, 200.0})
        EXPECT_GT(poisson_chi_square_p(mean, 200000, ++id), 1e-3) << "mean " << mean;
}

// Epanechnikov by the paper's rule: KS against F(x) = (2 + 3x − x³)/4, support [−1, 1],
// variance 1/5, and the rule itself on the words (first unless it is the largest).
TEST(Rng, EpanechnikovKolmogorovSmirnov) {
    RandomStream s(kSeed, 1, "epanechnikov");
    const int n = 100000;
    std::vector<double> v(n);
    double sum2 = 0.0;
    for (double& x : v) {
        x = s.epanechnikov();
        ASSERT_GE(x, -1.0);
        ASSERT_LE(x, 1.0);
        sum2 += x * x;
    }
    EXPECT_NEAR(sum2 / n, 0.2, 5.0 * std::sqrt((3.0 / 35 - 0.04) / n));  // E x⁴ = 3/35
    EXPECT_GT(ks_p_value(v, [](double x) { return (2.0 + 3.0 * x - x * x * x) / 4.0; }), 1e-3);
    EXPECT_LT(ks_p_value(v, [](double x) { return (1.0 + x) / 2.0; }), 1e-3);  // the test has power
    RandomStream a(kSeed, 2, "e"), b(kSeed, 2, "e");
    for (int i = 0; i < 100; ++i) {
        const double u1 = 2 * b.uniform() - 1, u2 = 2 * b.uniform() - 1, u3 = 2 * b.uniform() - 1;
        const bool first_highest = std::abs(u1) >= std::abs(u2) && std::abs(u1) >= std::abs(u3);
        EXPECT_EQ(a.epanechnikov(), first_highest ? u2 : u1);
    }
}

// Angle, sign, coin and uniform_index: ranges, balance, and uniform_index by chi-square.
TEST(Rng, AngleSignIndex) {
    RandomStream s(kSeed, 1, "misc");
    const int n = 70000;
    int heads = 0, positive = 0;
    std::vector<double> counts(7, 0.0);
    for (int i = 0; i < n; ++i) {
        const double a = s.angle();
        ASSERT_GE(a, 0.0);
        ASSERT_LT(a, 2.0 * M_PI);
        heads += s.coin();
        positive += s.sign() > 0;
        counts[s.uniform_index(7)] += 1.0;
    }
    EXPECT_NEAR(heads, n / 2.0, 5.0 * std::sqrt(n / 4.0));
    EXPECT_NEAR(positive, n / 2.0, 5.0 * std::sqrt(n / 4.0));
    double chi2 = 0.0;
    for (const double c : counts) chi2 += (c - n / 7.0) * (c - n / 7.0) / (n / 7.0);
    EXPECT_GT(gamma_q(3.0, 0.5 * chi2), 1e-3);
    EXPECT_EQ(s.uniform_index(1), 0u);
    EXPECT_THROW(s.uniform_index(0), Error);
}
