// The 1D Hermite-function basis against independent references: composite Gauss–Legendre
// quadrature (test_support) rather than the library's own Gauss–Hermite rule.
#include "shapesim/basis1d.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

using namespace shapesim;

namespace {
std::vector<double> phi(double u, int n_max) {
    std::vector<double> out(n_max + 1);
    hermite_functions(u, n_max, out.data());
    return out;
}
}  // namespace

TEST(Basis1d, FirstFunctionsMatchClosedForms) {
    for (double u : {-3.1, -0.4, 0.0, 0.7, 2.5}) {
        const auto p = phi(u, 3);
        const double g = std::pow(M_PI, -0.25) * std::exp(-0.5 * u * u);
        EXPECT_NEAR(p[0], g, 1e-16);
        EXPECT_NEAR(p[1], std::sqrt(2.0) * u * g, 1e-15);
        EXPECT_NEAR(p[2], (2 * u * u - 1) / std::sqrt(2.0) * g, 1e-15);  // H_2/√(2²·2!)
        EXPECT_NEAR(p[3], (8 * u * u * u - 12 * u) / std::sqrt(48.0) * g, 1e-14);
    }
}

// Orthonormality to 1e-12 for every n ≤ 60: φ_60 lives inside |u| < √121 = 11, so [−20, 20]
// in 80 panels of 30 Gauss–Legendre points resolves every product (entire functions).
TEST(Basis1d, OrthonormalToN60) {
    const int n_max = 60;
    std::vector<double> nodes, weights;
    test::gauss_legendre(30, nodes, weights);
    Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(n_max + 1, n_max + 1);
    const int panels = 80;
    const double a = -20, h = 40.0 / panels;
    for (int p = 0; p < panels; ++p)
        for (size_t i = 0; i < nodes.size(); ++i) {
            const double u = a + (p + 0.5) * h + 0.5 * h * nodes[i];
            const std::vector<double> values = phi(u, n_max);
            const Eigen::Map<const Eigen::VectorXd> v(values.data(), n_max + 1);
            gram += (0.5 * h * weights[i]) * v * v.transpose();
        }
    const double err = (gram - Eigen::MatrixXd::Identity(n_max + 1, n_max + 1)).cwiseAbs().maxCoeff();
    EXPECT_LT(err, 1e-12);
}

// The scaled basis B_n(x; β) = β^{-1/2} φ_n(x/β) is orthonormal for any β.
TEST(Basis1d, ScaledBasisOrthonormal) {
    for (double beta : {0.3, 1.0, 7.5}) {
        const int n_max = 20;
        for (int n = 0; n <= n_max; n += 3)
            for (int m = n; m <= n_max; m += 4) {
                const double v = test::integrate(
                    [&](double x) {
                        const Eigen::MatrixXd b = sampled_basis_1d(n_max, beta, x, 1);
                        return b(n, 0) * b(m, 0);
                    },
                    -15 * beta, 15 * beta, 60, 20);
                EXPECT_NEAR(v, n == m ? 1.0 : 0.0, 1e-12) << "beta " << beta << " n " << n << " m " << m;
            }
    }
}

// No NaN or Inf anywhere for n ≤ 200, |u| ≤ 50; values never exceed the bound |φ_n| < 1.
TEST(Basis1d, FiniteForHighOrderAndFarTails) {
    const int n_max = 200;
    for (double u = -50.0; u <= 50.0; u += 0.37) {
        const auto p = phi(u, n_max);
        std::vector<double> integrals(n_max + 1);
        hermite_integrals(u, u + 0.5, n_max, integrals.data());
        for (int n = 0; n <= n_max; ++n) {
            ASSERT_TRUE(std::isfinite(p[n])) << "n " << n << " u " << u;
            ASSERT_LT(std::abs(p[n]), 1.0) << "n " << n << " u " << u;
            ASSERT_TRUE(std::isfinite(integrals[n])) << "n " << n << " u " << u;
        }
    }
}

// Outside the turning point the recurrence with rescaling keeps relative accuracy where φ_0
// alone has underflowed: compare φ_150(45) with its logarithm from Stirling-free lgamma.
TEST(Basis1d, TailValueAfterUnderflowOfPhi0) {
    const int n = 150;
    const double u = 40.0;
    const auto p = phi(u, n);
    // Leading term of H_n(u) (2u)^n dominates far outside: log|φ_n| ≈
    //   n log(2u) − u²/2 − ½(n log 2 + lgamma(n+1) + ½ log π) + log(1 − n(n−1)/(4u²) + …)
    double series = 1.0, term = 1.0;
    for (int k = 1; 2 * k <= n; ++k) {
        term *= -double(n - 2 * k + 2) * (n - 2 * k + 1) / (4.0 * u * u * k);
        series += term;
    }
    const double log_expected = n * std::log(2 * u) - 0.5 * u * u -
                                0.5 * (n * std::log(2.0) + std::lgamma(n + 1.0) + 0.5 * std::log(M_PI)) +
                                std::log(series);
    ASSERT_GT(p[n], 0.0);
    EXPECT_NEAR(std::log(p[n]), log_expected, 1e-10);
}

// Pixel integrals equal brute-force Gauss–Legendre integration to 1e-12.
TEST(Basis1d, PixelIntegralsMatchBruteForce) {
    const int n_max = 40;
    for (double beta : {0.7, 1.9, 6.0})
        for (double offset : {-13.3, -2.71, 0.0, 0.45, 9.8}) {
            const Eigen::MatrixXd pix = pixel_basis_1d(n_max, beta, offset, 4);
            for (int i = 0; i < 4; ++i)
                for (int n = 0; n <= n_max; ++n) {
                    const double brute = test::integrate(
                        [&](double x) {
                            std::vector<double> v(n_max + 1);
                            hermite_functions(x / beta, n_max, v.data());
                            return v[n] / std::sqrt(beta);
                        },
                        offset + i - 0.5, offset + i + 0.5, 4, 30);
                    ASSERT_NEAR(pix(n, i), brute, 1e-12) << "beta " << beta << " offset " << offset << " n " << n;
                }
        }
}

// A pixel's order-0 integral is integral_phi0 of its own edges bit for bit, though each edge's
// erfc is computed once and shared with the next pixel: spans wholly on either side of the
// centre and across it, offsets whose edges land on the centre, and odd β (where a pixel's
// right edge and the next one's left edge are not always the same double).
TEST(Basis1d, SharedEdgesGiveEachPixelsOwnIntegral) {
    for (double beta : {0.3, 1.0, 2.3, 7.77})
        for (double offset : {-40.0, -17.37, -3.5, -0.5, 0.0, 0.5, 2.25, 11.1})
            for (int npix : {1, 2, 7, 33}) {
                const Eigen::MatrixXd pix = pixel_basis_1d(3, beta, offset, npix);
                for (int i = 0; i < npix; ++i) {
                    const double u_a = (offset + i - 0.5) / beta, u_b = (offset + i + 0.5) / beta;
                    double own[4];
                    hermite_integrals(u_a, u_b, 3, own);
                    ASSERT_EQ(pix(0, i), own[0] * std::sqrt(beta)) << beta << " " << offset << " " << i;
                }
            }
}

// pixel_basis_1d (four edges and four pixels at a time in lanes where the CPU has AVX2) gives
// the documented per-pixel computation bit for bit: φ at each edge by hermite_functions, ∫φ_0
// from the pixel's own edges, the recurrence I_{n+1} = √(n/(n+1)) I_{n−1} − √(2/(n+1))
// (φ_n(u_b) − φ_n(u_a)), times √β. Orders 0 … 40 and 300 (whose far edges need
// hermite_functions' rescaling), spans of every length mod 4.
TEST(Basis1d, PixelBasisIsThePerPixelRecurrence) {
    for (int n_max : {0, 1, 2, 7, 40, 300})
        for (double beta : {0.45, 2.3})
            for (double offset : {-30.2, -1.5, 0.3})
                for (int npix : {1, 3, 4, 5, 9, 62}) {
                    const Eigen::MatrixXd pix = pixel_basis_1d(n_max, beta, offset, npix);
                    std::vector<double> a(std::size_t(n_max) + 1), b(a.size()), I(a.size());
                    for (int i = 0; i < npix; ++i) {
                        hermite_functions((offset + i - 0.5) / beta, n_max, a.data());
                        hermite_functions((offset + (i + 1) - 0.5) / beta, n_max, b.data());
                        hermite_integrals((offset + i - 0.5) / beta, (offset + i + 0.5) / beta, 0,
                                          I.data());
                        if (n_max >= 1) I[1] = -std::sqrt(2.0) * (b[0] - a[0]);
                        for (int n = 1; n < n_max; ++n)
                            I[std::size_t(n) + 1] = std::sqrt(double(n) / (n + 1)) * I[std::size_t(n) - 1] -
                                                    std::sqrt(2.0 / (n + 1)) * (b[std::size_t(n)] - a[std::size_t(n)]);
                        for (int n = 0; n <= n_max; ++n)
                            ASSERT_EQ(pix(n, i), I[std::size_t(n)] * std::sqrt(beta))
                                << n_max << " " << beta << " " << offset << " " << npix << " " << i << " " << n;
                    }
                }
}

// Pixel integrals over a span tile it: the columns sum to the integral over the whole span,
// and far enough out to the full integral ∫ B_n = β^{1/2} M_0(n).
TEST(Basis1d, PixelIntegralsSumToTotal) {
    const int n_max = 30;
    const double beta = 2.3;
    const Eigen::MatrixXd pix = pixel_basis_1d(n_max, beta, -60.0, 121);
    const Eigen::MatrixXd moments = hermite_moments(0, n_max);
    for (int n = 0; n <= n_max; ++n)
        EXPECT_NEAR(pix.row(n).sum(), std::sqrt(beta) * moments(0, n), 1e-13) << n;
}

// The Gauss–Hermite rule integrates products of Hermite functions of total order ≤ 2K−1
// exactly (here: against orthonormality) and its nodes are roots of φ_K.
TEST(Basis1d, GaussHermiteExactness) {
    for (int k : {1, 2, 5, 16, 41, 100}) {
        const GaussHermite& rule = gauss_hermite(k);
        ASSERT_EQ(int(rule.nodes.size()), k);
        for (int a = 0; a < k; a += std::max(1, k / 7))
            for (int b = 0; a + b <= 2 * k - 1 && b < k; b += std::max(1, k / 5)) {
                double s = 0.0;
                for (int i = 0; i < k; ++i) {
                    std::vector<double> v(k);
                    hermite_functions(rule.nodes[i], k - 1, v.data());
                    s += rule.weights[i] * v[a] * v[b];
                }
                EXPECT_NEAR(s, a == b ? 1.0 : 0.0, 1e-13) << "K " << k << " a " << a << " b " << b;
            }
        for (double u : rule.nodes) EXPECT_NEAR(phi(u, k)[k], 0.0, 1e-13);
    }
}

// M_p(n) = ∫ u^p φ_n du from the ladder recurrences equals brute-force quadrature.
TEST(Basis1d, HermiteMomentsMatchQuadrature) {
    const int p_max = 4, n_max = 20;
    const Eigen::MatrixXd m = hermite_moments(p_max, n_max);
    for (int p = 0; p <= p_max; ++p)
        for (int n = 0; n <= n_max; ++n) {
            const double brute = test::integrate(
                [&](double u) { return std::pow(u, p) * phi(u, n_max)[n]; }, -25, 25, 50, 30);
            EXPECT_NEAR(m(p, n), brute, 1e-12 * std::max(1.0, std::abs(brute))) << p << " " << n;
        }
}
