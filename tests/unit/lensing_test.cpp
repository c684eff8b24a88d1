// Lensing fields (share/shapesim/lensing.hpp) against references that do not share their
// formulas: the NFW closed form against the density integrated along the line of sight and
// over the disc; distances against the Einstein–de Sitter closed form; the Gaussian random
// field's realised power, averaged over realisations, against the input P(ℓ).
#include "shapesim/lensing.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/error.hpp"

#include <boost/math/quadrature/exp_sinh.hpp>
#include <boost/math/quadrature/gauss_kronrod.hpp>
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

using namespace shapesim;

namespace {

// Σ(x)/(ρ_s r_s) = 2 ∫_0^∞ ρ(√(x²+z²)) dz with ρ(r)/ρ_s = 1/(r (1+r)²) (r in r_s).
double surface_density(double x) {
    boost::math::quadrature::exp_sinh<double> integrator;
    return 2.0 * integrator.integrate(
                     [x](double z) {
                         const double r = std::hypot(x, z);
                         return 1.0 / (r * (1.0 + r) * (1.0 + r));
                     },
                     1e-14);
}

// The mean of Σ inside x: the mass in the cylinder over πx². A shell of radius r lies wholly
// inside the cylinder for r < x, and a fraction 1 − √(1 − x²/r²) of it for r > x (r = x cosh u:
// 1 − tanh u), so M_cyl/(4π ρ_s r_s³) = ∫_0^x r²ρ dr + ∫_0^∞ r²ρ (1 − tanh u) x sinh u du.
double mean_surface_density(double x) {
    auto shell = [](double r) { return r / ((1.0 + r) * (1.0 + r)); };  // r² ρ(r)/ρ_s
    const double inside = boost::math::quadrature::gauss_kronrod<double, 61>::integrate(
        shell, 0.0, x, 15, 1e-15);
    boost::math::quadrature::exp_sinh<double> integrator;
    const double outside = integrator.integrate(
        [&](double u) {
            // 1 − tanh u = 2/(1 + e^{2u}), without the cancellation (< e^{-600} past u = 300).
            if (u > 300.0) return 0.0;
            return shell(x * std::cosh(u)) * 2.0 / (1.0 + std::exp(2.0 * u)) * x * std::sinh(u);
        },
        1e-14);
    return 4.0 * (inside + outside) / (x * x);
}

}  // namespace

TEST(Lensing, NfwClosedFormEqualsTheIntegratedDensity) {
    const double kappa_s = 0.37;
    for (double x : {0.02, 0.1, 0.5, 0.9, 0.99, 0.9999999, 1.0, 1.0000001, 1.01, 1.2, 2.0, 10.0, 80.0}) {
        SCOPED_TRACE("x = " + std::to_string(x));
        const NfwProfile p = nfw_profile(x, kappa_s);
        const double kappa = kappa_s * surface_density(x);
        const double mean = kappa_s * mean_surface_density(x);
        EXPECT_NEAR(p.kappa, kappa, 1e-10 * kappa);
        EXPECT_NEAR(p.gamma_t, mean - kappa, 1e-10 * (mean - kappa));
    }
    // Continuous through r_s: the series and the closed forms meet.
    const NfwProfile below = nfw_profile(std::sqrt(0.9), 1.0), above = nfw_profile(std::sqrt(1.1), 1.0);
    const NfwProfile below2 = nfw_profile(std::nextafter(std::sqrt(0.9), 0.0), 1.0);
    EXPECT_NEAR(below.kappa, below2.kappa, 1e-14);
    EXPECT_GT(below.kappa, above.kappa);
    EXPECT_THROW(nfw_profile(0.0, 1.0), Error);
}

TEST(Lensing, NfwHaloShearsTangentially) {
    const NfwHalo halo{100.0, 100.0, 1e15, 4.0, 0.3};
    const NfwLens lens(halo, Cosmology{}, 1.0, 0.2);
    // To the right of the halo a galaxy is stretched along y (e1 < 0), on the diagonal
    // across it (e2 < 0), at the same distance with the same |γ| and κ.
    const Convergence right = lens.at(150.0, 100.0), diagonal = lens.at(100.0 + 50.0 / std::sqrt(2.0),
                                                                         100.0 + 50.0 / std::sqrt(2.0));
    EXPECT_LT(right.gamma1, 0.0);
    EXPECT_NEAR(right.gamma2, 0.0, 1e-15);
    EXPECT_LT(diagonal.gamma2, 0.0);
    EXPECT_NEAR(diagonal.gamma1, 0.0, 1e-12);
    EXPECT_NEAR(right.kappa, diagonal.kappa, 1e-12);
    EXPECT_NEAR(std::hypot(right.gamma1, right.gamma2), std::hypot(diagonal.gamma1, diagonal.gamma2), 1e-12);
    // The profile at the radius the halo's own r_s and κ_s give.
    const double x = 50.0 * 0.2 / lens.r_s_arcsec();
    EXPECT_DOUBLE_EQ(right.kappa, nfw_profile(x, lens.kappa_s()).kappa);
    // A 10^15 M_sun cluster at z = 0.3: r_s of order an arcminute, κ_s of order 0.1–1.
    EXPECT_GT(lens.r_s_arcsec(), 30.0);
    EXPECT_LT(lens.r_s_arcsec(), 300.0);
    EXPECT_GT(lens.kappa_s(), 0.05);
    EXPECT_LT(lens.kappa_s(), 2.0);
    EXPECT_THROW(NfwLens(halo, Cosmology{}, 0.2, 0.2), Error);  // sources in front of the lens
}

TEST(Lensing, DistancesEqualTheEinsteinDeSitterClosedForm) {
    Cosmology eds;
    eds.omega_m = 1.0;
    const double c_over_h = 299792.458 / eds.h0;
    for (double z : {0.1, 0.5, 1.0, 3.0}) {
        const double exact = 2.0 * c_over_h * (1.0 - 1.0 / std::sqrt(1.0 + z));
        EXPECT_NEAR(eds.comoving_distance(z), exact, 1e-10 * exact);
    }
    // Σ_crit grows without bound as the lens nears the sources.
    const Cosmology lcdm;
    EXPECT_GT(lcdm.sigma_crit(0.5, 0.51), 10.0 * lcdm.sigma_crit(0.5, 1.5));
}

TEST(Lensing, ReducedShearRefusesStrongLensing) {
    const auto g = reduced(Convergence{0.2, 0.08, -0.04});
    ASSERT_TRUE(g);
    EXPECT_DOUBLE_EQ(g->g1, 0.1);
    EXPECT_DOUBLE_EQ(g->g2, -0.05);
    EXPECT_FALSE(g->conserve_flux);
    EXPECT_FALSE(reduced(Convergence{1.0, 0.0, 0.0}));
    EXPECT_FALSE(reduced(Convergence{0.5, 0.4, 0.3}));
    // Beyond the weak limits: |g| = 0.6 > 0.5, and μ = 1/((1−κ)²(1−|g|²)) = 11.1 > 10 at κ = 0.7.
    EXPECT_FALSE(reduced(Convergence{0.0, 0.6, 0.0}));
    EXPECT_TRUE(reduced(Convergence{0.0, 0.6, 0.0}, true, WeakLensingLimits{0.7, 10.0}));
    EXPECT_FALSE(reduced(Convergence{0.7, 0.0, 0.0}));
    EXPECT_TRUE(reduced(Convergence{0.7, 0.0, 0.0}, true, WeakLensingLimits{0.5, 12.0}));
}

TEST(Lensing, PowerSpectrumTableInterpolatesLogLog) {
    const PowerSpectrum p({10.0, 100.0, 1000.0}, {1e-6, 1e-8, 0.0});
    EXPECT_DOUBLE_EQ(p(10.0), 1e-6);
    EXPECT_NEAR(p(std::sqrt(1000.0)), 1e-7, 1e-20);
    EXPECT_NEAR(p(std::sqrt(1e5)), 0.5e-8, 1e-20);  // linear next to the zero
    EXPECT_EQ(p(5.0), 0.0);
    EXPECT_EQ(p(2000.0), 0.0);
    EXPECT_THROW(PowerSpectrum({10.0, 10.0}, {1.0, 1.0}), Error);
    EXPECT_THROW(PowerSpectrum({10.0, 20.0}, {1.0, -1.0}), Error);
}

namespace {

// The mean of P over the DFT modes of each bin (what the realised power estimates).
std::vector<double> expected_power(const PowerSpectrum& p, long nx, long ny, double h,
                                   const std::vector<double>& edges, double limit) {
    std::vector<double> sum(edges.size() - 1, 0.0), count(edges.size() - 1, 0.0);
    for (long j = 0; j < ny; ++j)
        for (long i = 0; i < nx; ++i) {
            const double si = i <= nx / 2 ? i : i - nx, sj = j <= ny / 2 ? j : j - ny;
            const double l = std::hypot(2 * pi * si / (nx * h), 2 * pi * sj / (ny * h));
            for (std::size_t b = 0; b + 1 < edges.size(); ++b)
                if (l >= edges[b] && l < edges[b + 1]) {
                    sum[b] += l < limit ? p(l) : 0.0;
                    count[b] += 1.0;
                }
        }
    for (std::size_t b = 0; b < sum.size(); ++b) sum[b] /= count[b];
    return sum;
}

struct Realised {
    std::vector<double> e, b;
};

// The power of `realisations` fields, sampled at the nodes (offset 0) or halfway between them
// (offset 0.5 node), averaged.
Realised average_power(const PowerSpectrum& e, const std::optional<PowerSpectrum>& b, double offset,
                       const std::vector<double>& edges, int realisations) {
    const FieldGeometry field = make_field(64.0 / 60.0, 64.0 / 60.0, 1.0, 0.0, 0.0);  // 64² at 1″
    GaussianFieldOptions o;
    o.spacing = 4.0;
    o.padding = 1.0;
    Realised out{std::vector<double>(edges.size() - 1, 0.0), std::vector<double>(edges.size() - 1, 0.0)};
    for (int r = 0; r < realisations; ++r) {
        o.seed = std::uint64_t(r + 1);
        const GaussianLensingField f(e, b, field, o);
        const long nx = f.nodes_x(), ny = f.nodes_y();
        std::vector<double> g1(std::size_t(nx * ny)), g2(g1.size());
        for (long j = 0; j < ny; ++j)
            for (long i = 0; i < nx; ++i) {
                // Node (i, j) is at pixel 0.5 + i h/scale.
                const double h = f.node_spacing();
                const Convergence c = offset == 0.0 ? f.node(i, j)
                                                    : f.at(0.5 + (i + offset) * h, 0.5 + (j + offset) * h);
                g1[std::size_t(j * nx + i)] = c.gamma1;
                g2[std::size_t(j * nx + i)] = c.gamma2;
            }
        const BinnedPower p = shear_power(g1, g2, nx, ny, f.node_spacing() * arcsec, edges);
        for (std::size_t k = 0; k < out.e.size(); ++k) {
            out.e[k] += p.e[k] / realisations;
            out.b[k] += p.b[k] / realisations;
        }
    }
    return out;
}

}  // namespace

TEST(Lensing, GaussianFieldHasTheInputPowerInEveryBinItResolves) {
    // A 64″ square at a 4″ band limit (nodes 1″ apart): modes from ℓ0 = 2π/64″ to π/4″. The
    // first bin holds the 12 modes up to 2ℓ0, then 6 log bins; a mode's power scatters as
    // much as its mean, so 1600 realisations hold the fewest-mode bin to ±1.3% (1σ).
    const PowerSpectrum e({1e3, 1e7}, {1e-9, 1e-15});  // P ∝ ℓ^-1.5
    const double h = 1.0 * arcsec, l0 = 2 * pi / (64 * h), limit = pi / (4.0 * arcsec);
    std::vector<double> edges{0.999 * l0};
    for (int k = 0; k <= 6; ++k) edges.push_back(2.01 * l0 * std::pow(limit / (2.01 * l0), k / 6.0));
    const std::vector<double> expected = expected_power(e, 64, 64, h, edges, limit);
    const Realised nodes = average_power(e, std::nullopt, 0.0, edges, 1600);
    for (std::size_t k = 0; k < expected.size(); ++k) {
        SCOPED_TRACE("bin " + std::to_string(k));
        EXPECT_NEAR(nodes.e[k] / expected[k], 1.0, 0.05);
        EXPECT_LT(nodes.b[k], 1e-20 * expected[k]);  // no B mode asked: none made
    }
    // Halfway between the nodes in both axes (the interpolation's worst place) the field keeps
    // its power to 5% up to the band's edge, and makes no B mode to speak of.
    const Realised between = average_power(e, std::nullopt, 0.5, edges, 400);
    for (std::size_t k = 2; k < expected.size(); ++k) {
        SCOPED_TRACE("bin " + std::to_string(k));
        EXPECT_NEAR(between.e[k] / expected[k], 1.0, 0.05);
        EXPECT_LT(between.b[k], 0.01 * expected[k]);
    }
}

TEST(Lensing, GaussianFieldBModeWhenAsked) {
    const PowerSpectrum e({1e3, 1e7}, {1e-9, 1e-9}), b({1e3, 1e7}, {0.5e-9, 0.5e-9});
    const double limit = pi / (4.0 * arcsec);
    const std::vector<double> edges{limit / 4, limit / 2, limit};  // 24 to 150 modes a bin
    const Realised r = average_power(e, b, 0.0, edges, 200);
    for (std::size_t k = 0; k + 1 < edges.size(); ++k) {
        EXPECT_NEAR(r.e[k] / 1e-9, 1.0, 0.05);
        EXPECT_NEAR(r.b[k] / 0.5e-9, 1.0, 0.05);
    }
}

TEST(Lensing, GaussianFieldIsTheSeedsAlone) {
    const PowerSpectrum e({1e3, 1e7}, {1e-9, 1e-15});
    const FieldGeometry field = make_field(2.0, 1.0, 0.1, 150.0, 2.0);
    GaussianFieldOptions o;
    o.seed = 5;
    const GaussianLensingField a(e, std::nullopt, field, o), b(e, std::nullopt, field, o);
    o.seed = 6;
    const GaussianLensingField c(e, std::nullopt, field, o);
    const Convergence ka = a.at(333.3, 444.4), kb = b.at(333.3, 444.4), kc = c.at(333.3, 444.4);
    EXPECT_EQ(ka.gamma1, kb.gamma1);
    EXPECT_EQ(ka.gamma2, kb.gamma2);
    EXPECT_EQ(ka.kappa, kb.kappa);
    EXPECT_NE(ka.gamma1, kc.gamma1);
    // Padding 2 over a 2′ × 1′ field at the default spacing (2′/128), 4 nodes a spacing:
    // 1024 × 512 nodes.
    EXPECT_EQ(a.nodes_x(), 1024);
    EXPECT_EQ(a.nodes_y(), 512);
    // A grid past the limit is refused, naming the spacing.
    o.spacing = 0.001;
    EXPECT_THROW(GaussianLensingField(e, std::nullopt, field, o), Error);
}
