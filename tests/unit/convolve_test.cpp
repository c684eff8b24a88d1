// Exact shapelet convolution (share/shapesim/convolve.hpp) against GalSim's exact reference
// series and images, closed forms (two Gaussians), brute-force numerical convolution of the
// point-sampled models, flux, and the least-squares inverses (deconvolution, difference kernel).
// The fixtures come from test_support (reference_convolutions).
#include "shapesim/convolve.hpp"

#include "shapesim/error.hpp"
#include "shapesim/polar.hpp"
#include "shapesim/render.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace shapesim;

namespace {

constexpr double kPi = 3.14159265358979323846;

// F = 2√π β Σ_{n even} a_{n,0} (DESIGN §2) and its scale 2√π β Σ |a_{n,0}|.
double flux_of(const ShapeletModel& m, bool absolute = false) {
    double sum = 0.0;
    for (int n = 0; n <= m.n_max; n += 2) {
        const double a = m.at(n, 0).real();
        sum += absolute ? std::abs(a) : a;
    }
    return 2.0 * std::sqrt(kPi) * m.beta_pix * sum;
}

// max |Δ| over the real parameters, and max |a| of the reference.
double max_abs_difference(const ShapeletModel& a, const ShapeletModel& b) {
    return (real_parameters(a) - real_parameters(b)).cwiseAbs().maxCoeff();
}
double max_abs(const ShapeletModel& a) { return real_parameters(a).cwiseAbs().maxCoeff(); }

// A deterministic random model (test_support): galaxy-like or fully random, off-centre.
ShapeletModel random_model(int n_max, double beta, unsigned seed, bool galaxy = true) {
    return test::random_model(n_max, beta, 10.3, 11.6, seed, galaxy);
}

}  // namespace

// C_000 of two Gaussians in closed form: B_0(α) ∗ B_0(b) = √(2π) π^{−1/4} √(αb/γ) B_0(γ).
TEST(Convolve, TensorOfTwoGaussiansIsClosedForm) {
    for (const auto& [alpha, b] : {std::pair{1.0, 1.0}, {2.7, 0.4}, {0.3, 5.0}}) {
        const ConvolutionTensor c(alpha, b, 3, 2);
        const double gamma = std::hypot(alpha, b);
        EXPECT_DOUBLE_EQ(c.gamma(), gamma);
        const double expected =
            std::sqrt(2.0 * kPi) * std::pow(kPi, -0.25) * std::sqrt(alpha * b / gamma);
        EXPECT_NEAR(c(0, 0, 0), expected, 1e-15 * expected);
        EXPECT_EQ(c(0, 0, 1), 0.0);  // parity
        EXPECT_EQ(c(1, 0, 3), 0.0);  // l > n + m
    }
}

// Σ_l C_nml B_l(x; γ) equals ∫ B_n(x′; α) B_m(x − x′; b) dx′ by the trapezoid rule on a fine
// grid (spectrally accurate for these entire, Gaussian-decaying integrands): 1e-13 absolute.
TEST(Convolve, TensorMatchesBruteForce1D) {
    const ConvolutionTensor c(1.3, 0.8, 7, 5);
    EXPECT_LT(test::tensor_brute_force_error(c, {-2.3, -0.7, 0.0, 0.45, 1.9, 3.6}, 0.01, 25.0),
              1e-13);
}

// (a) The 8 exact `result` series of convolved.jsonl, coefficient by coefficient, to
// 1e-10 · max|a| (README's tolerance), and their scale γ; then the images of convolved.fits
// to 1e-9 of the peak (README; the DFT images themselves carry ~6e-13).
TEST(Convolve, ReproducesReferenceSeriesAndImages) {
    const auto& lines = test::reference_convolutions();
    ASSERT_EQ(lines.size(), 8u);
    for (const auto& r : lines) {
        const std::string& hdu = r.record.hdu;
        for (const ShapeletModel* m : {&r.galaxy, &r.psf, &r.result})
            EXPECT_EQ(int(m->coeffs.size()), polar_count(m->n_max)) << hdu;
        const ShapeletModel h = convolve(r.galaxy, r.psf);
        ASSERT_EQ(h.n_max, r.result.n_max) << hdu;
        EXPECT_NEAR(h.beta_pix, r.result.beta_pix, 1e-14 * h.beta_pix) << hdu;
        EXPECT_EQ(h.x, r.result.x);
        EXPECT_EQ(h.y, r.result.y);
        EXPECT_LE(max_abs_difference(h, r.result), 1e-10 * max_abs(r.result)) << hdu;
        EXPECT_NEAR(flux_of(h), r.record.flux, 1e-12 * flux_of(h, true)) << hdu;

        const ImageArray& truth = r.image;
        ASSERT_EQ(truth.cols(), r.record.nx);
        ASSERT_EQ(truth.rows(), r.record.ny);
        const ImageArray image = render_stamp(h, r.record.nx, r.record.ny);
        const double peak = truth.abs().maxCoeff();
        EXPECT_LT((image - truth).abs().maxCoeff(), 1e-9 * peak) << hdu;
    }
}

// (b) Convolution equals brute-force numerical convolution of the point-sampled models
// (the paper's polar formula, `evaluate`) on a fine lattice of step δ: h(x) ≈ δ² Σ f g. The
// lattice sum of these entire functions converges spectrally (measured ≤ 4e-15 at this step);
// we ask 1e-8 of max|h|, the brief's tolerance.
TEST(Convolve, MatchesBruteForceConvolution2D) {
    struct Case {
        int n_f, n_g;
        double alpha, b;
        unsigned seed;
        bool galaxy;
    };
    for (const Case& k : {Case{8, 5, 2.2, 1.4, 11, true}, Case{6, 4, 1.1, 1.7, 12, false},
                          Case{3, 8, 2.6, 1.2, 13, true}}) {
        const ShapeletModel f = random_model(k.n_f, k.alpha, k.seed, k.galaxy);
        ShapeletModel g = random_model(k.n_g, k.b, k.seed + 100, true);
        g.x = 1e3;  // the PSF's own position plays no part
        const ShapeletModel h = convolve(f, g);
        // Step 0.25 (≥ 4 samples per β): the lattice sum reaches ~5e-15. Points (p, q) lattice
        // steps off the centre, |p| ≤ 24, |q| ≤ 21, every third.
        const double relative = test::lattice_convolution_error(f, g, h, 0.25, 24, 21, 3);
        EXPECT_LT(relative, 1e-8) << "n_f " << k.n_f << " n_g " << k.n_g;
    }
}

// (c) flux_h = flux_f · flux_g exactly (to 1e-12 of the flux scale 2√π γ Σ|a_{n,0}|), with no
// implicit normalisation of the PSF.
TEST(Convolve, FluxMultiplies) {
    for (unsigned seed = 1; seed <= 6; ++seed) {
        const ShapeletModel f = random_model(2 * seed + 1, 0.8 + 0.5 * seed, seed, seed % 2);
        const ShapeletModel g = random_model(seed + 2, 2.1 - 0.2 * seed, seed + 50, true);
        const ShapeletModel h = convolve(f, g);
        EXPECT_NEAR(flux_of(h), flux_of(f) * flux_of(g), 1e-12 * flux_of(h, true));
    }
}

// A workspace carried over galaxies of several orders (its projection kept per output order)
// gives every one the bits a fresh workspace gives.
TEST(Convolve, ReusedWorkspaceEqualsFreshOne) {
    const CartesianModel psf = to_cartesian(random_model(4, 1.4, 90));
    ConvolveWorkspace carried;
    const int orders[] = {3, 2, 0, 7, 3, 1, 12, 2};
    for (int k = 0; k < 8; ++k) {
        const CartesianModel galaxy =
            to_cartesian(random_model(orders[k], 0.7 + 0.3 * k, 100 + unsigned(k)));
        const CartesianModel reused = convolve(galaxy, psf, carried);
        ConvolveWorkspace fresh;
        const CartesianModel alone = convolve(galaxy, psf, fresh);
        ASSERT_EQ(reused.n_max, alone.n_max);
        EXPECT_EQ(reused.beta_pix, alone.beta_pix);
        EXPECT_TRUE((reused.b.array() == alone.b.array()).all()) << "galaxy " << k;
    }
}

// Conventions: the result sits at the galaxy's centre, with β = γ and n_max N_f + N_g; the
// PSF's position is ignored; f ∗ g = g ∗ f coefficient by coefficient.
TEST(Convolve, ConventionsAndCommutation) {
    const ShapeletModel f = random_model(7, 2.0, 21);
    ShapeletModel g = random_model(4, 1.2, 22);
    const ShapeletModel h = convolve(f, g);
    EXPECT_EQ(h.x, f.x);
    EXPECT_EQ(h.y, f.y);
    EXPECT_EQ(h.n_max, 11);
    EXPECT_DOUBLE_EQ(h.beta_pix, std::hypot(2.0, 1.2));
    g.x += 17.5;
    g.y -= 3.25;
    EXPECT_EQ(real_parameters(convolve(f, g)), real_parameters(h));
    const ShapeletModel swapped = convolve(g, f);
    EXPECT_LT(max_abs_difference(swapped, h), 1e-14 * max_abs(h));
}

// The linear maps reproduce `convolve` (for fitting PSF-convolved models).
TEST(Convolve, LinearMapsMatchConvolve) {
    const ShapeletModel g = random_model(6, 1.5, 31);
    for (const int n_f : {0, 3, 10}) {
        const ShapeletModel f = random_model(n_f, 2.4, 30 + n_f, false);
        const ShapeletModel h = convolve(f, g);
        const Eigen::MatrixXd m = convolution_matrix(g, f.beta_pix, n_f);
        ASSERT_EQ(m.rows(), real_count(n_f + 6));
        ASSERT_EQ(m.cols(), real_count(n_f));
        const Eigen::VectorXd mapped = m * real_parameters(f);
        EXPECT_LT((mapped - real_parameters(h)).cwiseAbs().maxCoeff(), 1e-13 * max_abs(h));
        const Eigen::MatrixXd l = cartesian_convolution_matrix(to_cartesian(g), f.beta_pix, n_f);
        const Eigen::VectorXd packed = l * pack_cartesian(to_cartesian(f).b, n_f);
        EXPECT_LT((packed - pack_cartesian(to_cartesian(h).b, h.n_max)).cwiseAbs().maxCoeff(),
                  1e-13 * max_abs(h));
    }
}

// (d) Deconvolution inverts convolution where well posed (γ > b; noise-free h = g ∗ f with
// n_max(f) ≤ n_max_out) to 1e-10 · max|a|; asking a higher n_max_out gives zeros above.
// Condition numbers of these maps are ≤ ~1e3 (rounding × κ ≪ 1e-10).
TEST(Convolve, DeconvolutionInvertsConvolution) {
    struct Case {
        int n_f, n_g;
        double alpha, b;
    };
    for (const Case& k : {Case{4, 4, 2.0, 1.5}, Case{8, 6, 3.0, 1.3}, Case{12, 8, 2.5, 1.2},
                          Case{0, 5, 1.0, 1.6}}) {
        const ShapeletModel f = random_model(k.n_f, k.alpha, 40 + k.n_f, false);
        const ShapeletModel g = random_model(k.n_g, k.b, 41 + k.n_g, true);
        const ShapeletModel h = convolve(f, g);
        InverseReport report;
        const ShapeletModel back = deconvolve(h, g, k.n_f + 2, &report);
        EXPECT_NEAR(back.beta_pix, k.alpha, 1e-14 * k.alpha);
        EXPECT_EQ(back.x, h.x);
        EXPECT_LT(max_abs_difference(back, with_n_max(f, k.n_f + 2)), 1e-10 * max_abs(f))
            << "n_f " << k.n_f << " cond " << report.condition_number;
        EXPECT_LT(report.relative_residual, 1e-12);
        EXPECT_LT(report.condition_number, 1e4);
    }
}

TEST(Convolve, DeconvolutionRejectsIllPosedInput) {
    const ShapeletModel g = random_model(3, 1.5, 51);
    const ShapeletModel narrow = random_model(3, 1.5, 52);
    EXPECT_THROW(deconvolve(narrow, g, 3), Error);  // γ = b: nothing left to deconvolve
    ShapeletModel zero_psf(0, 0, 1.0, 2);
    EXPECT_THROW(deconvolve(random_model(3, 2.0, 53), zero_psf, 3), Error);
}

// (e) The difference kernel between Gaussians is the exact Gaussian: new = N(b_new) with flux
// F_new, old = N(b_old) with flux F_old ⇒ k = Gaussian of scale √(b_new² − b_old²) and flux
// F_new / F_old; all higher coefficients vanish and the residual is zero.
TEST(Convolve, DifferenceKernelOfGaussiansIsGaussian) {
    const double b_old = 1.2, b_new = 2.0, flux_old = 0.9, flux_new = 1.1;
    ShapeletModel old_psf(3.0, 4.0, b_old, 0), new_psf(5.0, 6.0, b_new, 0);
    old_psf.at(0, 0) = flux_old / (2.0 * std::sqrt(kPi) * b_old);
    new_psf.at(0, 0) = flux_new / (2.0 * std::sqrt(kPi) * b_new);
    const DifferenceKernel d = difference_kernel(old_psf, new_psf, 6);
    const double beta_k = std::sqrt(b_new * b_new - b_old * b_old);
    EXPECT_NEAR(d.kernel.beta_pix, beta_k, 1e-15 * beta_k);
    EXPECT_EQ(d.kernel.x, new_psf.x);
    ShapeletModel exact(new_psf.x, new_psf.y, beta_k, 6);
    exact.at(0, 0) = flux_new / flux_old / (2.0 * std::sqrt(kPi) * beta_k);
    EXPECT_LT(max_abs_difference(d.kernel, exact), 1e-13 * max_abs(exact));
    EXPECT_LT(d.report.relative_residual, 1e-13);
}

// A general difference kernel: new = k ∗ old is recovered exactly; a new PSF that no kernel of
// the order reaches (narrower along one axis than the old one) is flagged by the residual.
TEST(Convolve, DifferenceKernelRecoversKernelAndFlagsResidual) {
    const ShapeletModel old_psf = random_model(6, 1.3, 61);
    const ShapeletModel k_true = random_model(4, 1.1, 62);
    ShapeletModel new_psf = convolve(k_true, old_psf);
    const DifferenceKernel d = difference_kernel(old_psf, new_psf, 4);
    EXPECT_LT(max_abs_difference(d.kernel, k_true), 1e-10 * max_abs(k_true));
    EXPECT_LT(d.report.relative_residual, 1e-12);

    ShapeletModel unreachable = random_model(8, 1.8, 63, false);
    const DifferenceKernel bad = difference_kernel(old_psf, unreachable, 4);
    EXPECT_GT(bad.report.relative_residual, 1e-3);
    EXPECT_THROW(difference_kernel(new_psf, old_psf, 4), Error);
}
