// The polar basis χ_{n,m} and the polar ↔ Cartesian change of basis.
#include "shapesim/polar.hpp"

#include "shapesim/basis1d.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

using namespace shapesim;

TEST(Polar, PackedOrder) {
    const auto idx = polar_indices(4);
    ASSERT_EQ(int(idx.size()), polar_count(4));
    const int expected[][2] = {{0, 0}, {1, 1}, {2, 0}, {2, 2}, {3, 1}, {3, 3}, {4, 0}, {4, 2}, {4, 4}};
    for (int k = 0; k < 9; ++k) {
        EXPECT_EQ(idx[k].n, expected[k][0]);
        EXPECT_EQ(idx[k].m, expected[k][1]);
        EXPECT_EQ(polar_index(idx[k].n, idx[k].m), k);
    }
    EXPECT_EQ(real_count(15), 136);
}

// χ_{0,0} is the normalised Gaussian; χ_{2,0} and χ_{1,1} from the paper's eq. 2 by hand.
TEST(Polar, LowOrdersMatchClosedForms) {
    const double beta = 1.7, dx = 0.9, dy = -1.3;
    std::vector<Complex> chi(polar_count(2));
    polar_basis(dx, dy, beta, 2, chi.data());
    const double r2 = (dx * dx + dy * dy) / (beta * beta);
    const double g = std::exp(-0.5 * r2) / (beta * std::sqrt(M_PI));
    EXPECT_NEAR(std::abs(chi[polar_index(0, 0)] - g), 0.0, 1e-16);
    // L_1^0(t) = 1 − t, sign (−1)^1
    EXPECT_NEAR(std::abs(chi[polar_index(2, 0)] - (-(1 - r2) * g)), 0.0, 1e-15);
    // χ_{1,1} = (r/β) e^{iθ} g
    EXPECT_NEAR(std::abs(chi[polar_index(1, 1)] - Complex(dx, dy) / beta * g), 0.0, 1e-15);
}

// Orthonormality to 1e-12 for every n ≤ 60. The angular integral of e^{i(m−m')θ} is 2π δ_mm',
// so what remains is the radial one: 2π ∫ R_{n,m} R_{n',m} r dr = δ_nn', by composite
// Gauss–Legendre on [0, 18] (χ_60 lives inside r < √122 ≈ 11).
TEST(Polar, OrthonormalToN60) {
    const int n_max = 60;
    std::vector<double> nodes, weights;
    test::gauss_legendre(30, nodes, weights);
    const int panels = 60;
    const double h = 18.0 / panels;
    // Rows: quadrature points, scaled by √(weight); the Gram matrix is then VᵀV.
    Eigen::MatrixXd v(panels * nodes.size(), polar_count(n_max));
    std::vector<Complex> chi(polar_count(n_max));
    for (int p = 0; p < panels; ++p)
        for (size_t i = 0; i < nodes.size(); ++i) {
            const double r = (p + 0.5) * h + 0.5 * h * nodes[i];
            polar_basis(r, 0.0, 1.0, n_max, chi.data());  // θ = 0: values are real radial parts
            const double w = std::sqrt(2 * M_PI * r * 0.5 * h * weights[i]);
            for (size_t k = 0; k < chi.size(); ++k) v(p * nodes.size() + i, k) = w * chi[k].real();
        }
    const Eigen::MatrixXd gram = v.transpose() * v;
    const auto idx = polar_indices(n_max);
    double worst = 0.0;
    for (size_t a = 0; a < idx.size(); ++a)
        for (size_t b = 0; b < idx.size(); ++b) {
            if (idx[a].m != idx[b].m) continue;  // orthogonal through the angle
            worst = std::max(worst, std::abs(gram(a, b) - (a == b ? 1.0 : 0.0)));
        }
    EXPECT_LT(worst, 1e-12);
}

TEST(Polar, FiniteForHighOrderAndFarTails) {
    const int n_max = 200;
    std::vector<Complex> chi(polar_count(n_max));
    for (double r : {0.0, 0.3, 5.0, 19.0, 35.0, 50.0}) {
        polar_basis(r * 0.6, r * 0.8, 1.0, n_max, chi.data());
        for (const Complex& c : chi) ASSERT_TRUE(std::isfinite(c.real()) && std::isfinite(c.imag())) << r;
    }
}

// The ladder-built T^{(n)} equals the overlap integrals ∫∫ χ_{n,m} φ_{n1}(x) φ_{n−n1}(y) of the
// paper's formula, by (n+1)²-point Gauss–Hermite quadrature (exact: polynomial × Gaussian).
TEST(Polar, ChangeOfBasisMatchesQuadratureOfEq2) {
    for (int n = 0; n <= 16; ++n) {
        const GaussHermite& rule = gauss_hermite(n + 1);
        Eigen::MatrixXcd t = Eigen::MatrixXcd::Zero(n + 1, n + 1);
        std::vector<Complex> chi(polar_count(n));
        std::vector<double> phi_x(n + 1), phi_y(n + 1);
        for (int i = 0; i <= n; ++i)
            for (int j = 0; j <= n; ++j) {
                polar_basis(rule.nodes[i], rule.nodes[j], 1.0, n, chi.data());
                hermite_functions(rule.nodes[i], n, phi_x.data());
                hermite_functions(rule.nodes[j], n, phi_y.data());
                const double w = rule.weights[i] * rule.weights[j];
                for (int m = -n; m <= n; m += 2) {
                    const Complex c = m >= 0 ? chi[polar_index(n, m)] : std::conj(chi[polar_index(n, -m)]);
                    for (int n1 = 0; n1 <= n; ++n1) t((n + m) / 2, n1) += w * c * phi_x[n1] * phi_y[n - n1];
                }
            }
        EXPECT_LT((t - polar_cartesian_matrix(n)).cwiseAbs().maxCoeff(), 1e-13) << "n " << n;
    }
}

// At high order, against the paper's formula point by point: Σ T_{m,n1} φ_{n1}(x) φ_{n−n1}(y)
// equals χ_{n,m}(x, y) to 1e-12 of max|χ| for n up to 200 (measured ≤ 2e-13: the ladder's error
// does not grow; without the unitary correction it reached 1e-7 at n = 200).
TEST(Polar, ChangeOfBasisMatchesEq2PointwiseToN200) {
    for (int n : {40, 101, 157, 200}) {
        const Eigen::MatrixXcd& t = polar_cartesian_matrix(n);
        std::vector<Complex> chi(polar_count(n));
        std::vector<double> phi_x(n + 1), phi_y(n + 1);
        double worst = 0.0, peak = 0.0;
        for (double x = -18; x <= 18; x += 2.37)
            for (double y = -17; y <= 18; y += 2.91) {
                polar_basis(x, y, 1.0, n, chi.data());
                hermite_functions(x, n, phi_x.data());
                hermite_functions(y, n, phi_y.data());
                for (int m = n % 2; m <= n; m += 2) {
                    Complex sum = 0.0;
                    for (int n1 = 0; n1 <= n; ++n1) sum += t((n + m) / 2, n1) * phi_x[n1] * phi_y[n - n1];
                    worst = std::max(worst, std::abs(sum - chi[polar_index(n, m)]));
                    peak = std::max(peak, std::abs(chi[polar_index(n, m)]));
                }
            }
        EXPECT_LT(worst, 1e-12 * peak) << "n " << n;
    }
}

// T^{(n)} is unitary for every n ≤ 200.
TEST(Polar, ChangeOfBasisUnitary) {
    for (int n = 0; n <= 200; ++n) {
        const Eigen::MatrixXcd& t = polar_cartesian_matrix(n);
        const double err =
            (t * t.adjoint() - Eigen::MatrixXcd::Identity(n + 1, n + 1)).cwiseAbs().maxCoeff();
        ASSERT_LT(err, 1e-12) << "n " << n;
    }
}

// polar → Cartesian → polar returns the coefficients to 1e-12 (n_max up to 60).
TEST(Polar, RoundTrip) {
    for (int n_max : {0, 1, 2, 5, 15, 31, 60}) {
        const ShapeletModel model = test::random_model(n_max, 2.0, 10.0, 11.0, 100 + n_max, false);
        const ShapeletModel back = to_polar(to_cartesian(model));
        double err = 0.0;
        for (size_t k = 0; k < model.coeffs.size(); ++k)
            err = std::max(err, std::abs(back.coeffs[k] - model.coeffs[k]));
        EXPECT_LT(err, 1e-12) << "n_max " << n_max;
        for (int n = 0; n <= n_max; n += 2) EXPECT_EQ(back.at(n, 0).imag(), 0.0);
    }
}

// The polar model evaluated directly equals its Cartesian transform evaluated as
// Σ b B_{n1}(x) B_{n2}(y), at arbitrary points.
TEST(Polar, PolarEqualsCartesianPointwise) {
    const ShapeletModel model = test::random_model(12, 1.6, 5.3, -2.2, 7);
    const CartesianModel cart = to_cartesian(model);
    for (double x : {-3.0, 0.4, 5.3, 8.8})
        for (double y : {-6.1, -2.2, 0.0, 3.3}) {
            const Eigen::MatrixXd bx = sampled_basis_1d(12, 1.6, x - cart.x, 1);
            const Eigen::MatrixXd by = sampled_basis_1d(12, 1.6, y - cart.y, 1);
            const double value = (bx.transpose() * cart.b * by)(0, 0);
            EXPECT_NEAR(evaluate(model, x, y), value, 1e-13) << x << "," << y;
        }
}
