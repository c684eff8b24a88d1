// optimize.hpp's Brent root finder (to its tolerance, in few steps; an end that is a root) and
// its golden-section search: the minimum of a parabola within the tolerance, each
// point evaluated once and in order, every dropped point reported, the golden ratio's
// bracket shrinking.
#include "shapesim/optimize.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <vector>

using namespace shapesim;

TEST(GoldenSection, FindsAParabolasMinimumWithinTheTolerance) {
    std::vector<double> calls, dropped;
    const auto f = [&](double x) {
        calls.push_back(x);
        return (x - 1.3) * (x - 1.3);
    };
    const auto bracket = golden_section(f, 0.0, 3.0, 1e-6, std::less<double>(),
                                        [&](double value) { dropped.push_back(value); });
    EXPECT_LT(bracket.c, bracket.d);
    EXPECT_NEAR(bracket.c, 1.3, 1e-6);
    EXPECT_NEAR(bracket.d, 1.3, 1e-6);
    EXPECT_EQ(bracket.fc, f(bracket.c));
    calls.pop_back();
    // Two points to start, then one a step; the bracket shrinks by g each step.
    const double g = 0.5 * (std::sqrt(5.0) - 1.0);
    const int steps = int(std::ceil(std::log(1e-6 / (3.0 * g)) / std::log(g)));
    EXPECT_NEAR(double(calls.size()), 2.0 + steps, 1.0);
    EXPECT_EQ(dropped.size() + 2, calls.size());
    EXPECT_DOUBLE_EQ(calls[0], 3.0 - g * 3.0);
    EXPECT_DOUBLE_EQ(calls[1], g * 3.0);
}

TEST(GoldenSection, ANarrowBracketIsEvaluatedOnlyAtItsTwoPoints) {
    int calls = 0;
    const auto bracket = golden_section([&](double x) { ++calls; return x; }, 1.0, 1.001, 0.01,
                                        std::less<double>(), [](double) {});
    EXPECT_EQ(calls, 2);
    EXPECT_LT(bracket.fc, bracket.fd);  // f(x) = x: the lower point is the lower value
}

TEST(BrentRoot, FindsTheRootOfABracketWithinTheTolerance) {
    int calls = 0;
    const auto f = [&](double x) {
        ++calls;
        return std::cos(x);
    };
    const double root = brent_root(f, 0.0, 2.0, std::cos(0.0), std::cos(2.0), 1e-10);
    EXPECT_NEAR(root, M_PI / 2.0, 1e-10);
    EXPECT_LT(calls, 12);  // superlinear: bisection alone would take 35
    // An end that is a root is returned without a call.
    calls = 0;
    EXPECT_EQ(brent_root(f, M_PI / 2.0, 3.0, 0.0, std::cos(3.0), 1e-10), M_PI / 2.0);
    EXPECT_EQ(calls, 0);
}
