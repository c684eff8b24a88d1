// lane::log, lane::exp and lane::asin: within 1 ulp of libm over their domains, and the same bits in a
// vector lane as for a double (what lets photon noise draw four pixels at a time and still
// give the per-pixel draw).

#include "shapesim/lane_math.hpp"
#include "shapesim/rng.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

using namespace shapesim;

namespace {

// Distance in units in the last place between two finite doubles of the same sign.
std::int64_t ulps(double a, double b) {
    const auto ia = std::int64_t(lane::bits(a)), ib = std::int64_t(lane::bits(b));
    return ia > ib ? ia - ib : ib - ia;
}

// f (lane::log, exp or asin, as a generic lambda) of each x in lanes and alone: the same bits,
// and within 1 ulp of libm's.
template <class F, class Libm>
void expect_close_and_lanes_equal(const std::vector<double>& xs, F f, Libm libm, const char* what) {
    std::int64_t worst = 0;
    for (std::size_t i = 0; i + 4 <= xs.size(); i += 4) {
        const double* x = &xs[i];
        const lane::Doubles4 y = f(lane::Doubles4{x[0], x[1], x[2], x[3]});
        for (int j = 0; j < 4; ++j) {
            const double s = f(x[j]);
            ASSERT_EQ(lane::bits(y[j]), lane::bits(s)) << what << " lane " << j << " of x = " << x[j];
            worst = std::max(worst, ulps(s, libm(x[j])));
        }
    }
    EXPECT_LE(worst, 1) << what;
}

}  // namespace

TEST(LaneMath, LogWithinAnUlpAndLanesEqualScalar) {
    RandomStream r(3, 1, "lane log");
    std::vector<double> xs;
    for (int i = 0; i < 400000; ++i) xs.push_back(std::exp(r.uniform(-700.0, 700.0)));
    for (int i = 0; i < 400000; ++i) xs.push_back(r.uniform(0.5, 2.0));   // near 1: f small
    for (int i = 0; i < 4000; ++i) xs.push_back(1.0 + (i - 2000) * 0x1.0p-52);
    for (const double x : {1.0, 2.0, 0.5, 10.0, std::numeric_limits<double>::min(),
                           std::numeric_limits<double>::max(), 0x1.6a09e667f3bcdp-1, 0x1.6a09e667f3bccp-1})
        xs.push_back(x);
    while (xs.size() % 4) xs.push_back(1.0);
    expect_close_and_lanes_equal(
        xs, [](auto x) __attribute__((always_inline)) { return lane::log(x); },
        [](double x) { return std::log(x); }, "log");
    EXPECT_EQ(lane::log(1.0), 0.0);
}

TEST(LaneMath, ExpWithinAnUlpAndLanesEqualScalar) {
    RandomStream r(3, 2, "lane exp");
    std::vector<double> xs;
    for (int i = 0; i < 400000; ++i) xs.push_back(r.uniform(-708.0, 709.0));
    for (int i = 0; i < 400000; ++i) xs.push_back(-r.uniform(0.0, 10.0));  // photon noise's e^{−μ}
    for (int i = 0; i < 4000; ++i) xs.push_back((i - 2000) * 1e-10);
    for (const double x : {0.0, -0.0, 1.0, -1.0, 0.5 * 0.6931471805599453, -708.0, 709.0})
        xs.push_back(x);
    while (xs.size() % 4) xs.push_back(0.0);
    expect_close_and_lanes_equal(
        xs, [](auto x) __attribute__((always_inline)) { return lane::exp(x); },
        [](double x) { return std::exp(x); }, "exp");
    EXPECT_EQ(lane::exp(0.0), 1.0);
}

TEST(LaneMath, AsinWithinAnUlpAndLanesEqualScalar) {
    RandomStream r(3, 4, "lane asin");
    std::vector<double> xs;
    for (int i = 0; i < 400000; ++i) xs.push_back(r.uniform(-1.0, 1.0));
    for (int i = 0; i < 100000; ++i) xs.push_back(1.0 - std::exp(r.uniform(-36.0, 0.0)));  // near 1
    for (int i = 0; i < 100000; ++i) xs.push_back(std::exp(r.uniform(-40.0, 0.0)));  // near 0
    for (int i = 0; i < 4000; ++i) {  // about the branches' edges ½ and 0.975
        xs.push_back(0.5 + (i - 2000) * 0x1.0p-52);
        xs.push_back(0x1.f333300000000p-1 + (i - 2000) * 0x1.0p-52);
    }
    for (const double x : {0.0, -0.0, 1.0, -1.0, 0.5, -0.5, 0x1.0p-27, 0x1.fffffffffffffp-28, 0.975})
        xs.push_back(x);
    while (xs.size() % 4) xs.push_back(0.0);
    expect_close_and_lanes_equal(
        xs, [](auto x) __attribute__((always_inline)) { return lane::asin(x); },
        [](double x) { return std::asin(x); }, "asin");
    EXPECT_EQ(lane::bits(lane::asin(0.0)), lane::bits(0.0));
    EXPECT_EQ(lane::bits(lane::asin(-0.0)), lane::bits(-0.0));
    EXPECT_EQ(lane::asin(1.0), std::asin(1.0));
    EXPECT_EQ(lane::asin(-1.0), -std::asin(1.0));
}

// ln k! against the exact sum of logs (long double), and lanes against the scalar, across the
// table/Stirling switch at 20.
TEST(LaneMath, LogFactorial) {
    const double* small = detail::small_log_factorials();
    long double sum = 0.0L;
    for (int k = 0; k <= 2000; ++k) {
        if (k > 1) sum += std::log((long double)k);
        const double got = detail::log_factorial(double(k));
        EXPECT_NEAR(got, double(sum), 4e-16 * std::max(1.0, double(sum))) << k;
        const lane::Doubles4 kk = {double(k), double(k + 1), double(k / 2), -1.0};
        const lane::Doubles4 lanes = detail::log_factorial(kk, small);
        for (int j = 0; j < 3; ++j) ASSERT_EQ(lanes[j], detail::log_factorial(kk[j])) << kk[j];
    }
}
