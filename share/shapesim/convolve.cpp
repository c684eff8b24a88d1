#include "shapesim/convolve.hpp"

#include "shapesim/basis1d.hpp"
#include "shapesim/error.hpp"
#include "shapesim/polar.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace shapesim {

namespace {
constexpr double kSqrtTwoPi = 2.50662827463100050242;  // √(2π)

// σ_n = (−1)^{⌊n/2⌋}: the real part of the Fourier phase (−i)^n up to (−i)^{n mod 2}.
double sigma_sign(int n) { return ((n / 2) % 2 == 0) ? 1.0 : -1.0; }

void require_scale(double beta, const char* what) {
    if (!(beta > 0.0) || !std::isfinite(beta))
        throw Error(std::string(what) + ": beta must be finite and > 0, got " +
                    std::to_string(beta));
}

void require_cartesian(const CartesianModel& model, const char* what) {
    require_scale(model.beta_pix, what);
    require(model.n_max >= 0 && model.b.rows() == model.n_max + 1 &&
                model.b.cols() == model.n_max + 1,
            std::string(what) + ": coefficient matrix does not match n_max");
}

// out(n, i) = σ_n φ_n(scale · u_i) (× W_i when `weighted`), n = 0..n_max, on the rule's nodes.
void signed_basis_at_nodes(const GaussHermite& rule, double scale, int n_max, bool weighted,
                           Eigen::MatrixXd& out) {
    const int k = int(rule.nodes.size());
    out.resize(n_max + 1, k);
    for (int i = 0; i < k; ++i) {
        hermite_functions(scale * rule.nodes[i], n_max, out.col(i).data());
        if (weighted) out.col(i) *= rule.weights[i];
    }
    for (int n = 0; n <= n_max; ++n)
        if (sigma_sign(n) < 0) out.row(n) *= -1.0;
}

// c_0 = √(2π) √(αb/γ): the constant of the 1D tensor (docs/algorithms.md#convolution).
double tensor_constant(double alpha, double b, double gamma) {
    return kSqrtTwoPi * std::sqrt(alpha * b / gamma);
}

// Zero the entries of a Cartesian coefficient matrix with n1 + n2 > n_max (rounding residue).
void clear_above_order(Eigen::MatrixXd& b, int n_max) {
    for (int n1 = 0; n1 <= n_max; ++n1)
        for (int n2 = n_max - n1 + 1; n2 <= n_max; ++n2) b(n1, n2) = 0.0;
}
}  // namespace

double convolved_beta(double alpha, double b) { return std::hypot(alpha, b); }

ConvolutionTensor::ConvolutionTensor(double alpha, double b, int n_f, int n_g)
    : alpha_(alpha), b_(b), gamma_(convolved_beta(alpha, b)), n_f_(n_f), n_g_(n_g) {
    require_scale(alpha, "ConvolutionTensor");
    require_scale(b, "ConvolutionTensor");
    require(n_f >= 0 && n_g >= 0, "ConvolutionTensor: orders must be >= 0");
    const int n_out = n_f + n_g;
    // K = N + 1 nodes integrate polynomials of degree ≤ 2N + 1 ≥ n + m + l exactly.
    const GaussHermite& rule = gauss_hermite(n_out + 1);
    Eigen::MatrixXd d_f, d_g, project;
    signed_basis_at_nodes(rule, alpha_ / gamma_, n_f, false, d_f);
    signed_basis_at_nodes(rule, b_ / gamma_, n_g, false, d_g);
    signed_basis_at_nodes(rule, 1.0, n_out, true, project);
    const double c0 = tensor_constant(alpha_, b_, gamma_);
    slices_.resize(n_g + 1);
    for (int m = 0; m <= n_g; ++m) {
        Eigen::MatrixXd& s = slices_[m];
        s.noalias() = c0 * (d_f * d_g.row(m).asDiagonal()) * project.transpose();
        for (int n = 0; n <= n_f; ++n) {
            // (−1)^{ε_n ε_m}, then the exact zeros: l > n + m or n + m + l odd.
            if (n % 2 == 1 && m % 2 == 1) s.row(n) *= -1.0;
            for (int l = 0; l <= n_out; ++l)
                if (l > n + m || (n + m + l) % 2 == 1) s(n, l) = 0.0;
        }
    }
}

namespace {
// PSF transforms on the node grid, split by the parities (r, s) of (m1, m2):
// G_rs(i, j) = Σ_{m1 ≡ r, m2 ≡ s} g(m1, m2) D(m1, i) D(m2, j). The parity sets the sign
// (−1)^{ε_n1 r + ε_n2 s} of the galaxy terms, i.e. a reflection of F in u_x (r = 1) and in
// u_y (s = 1), exact on the symmetric Gauss–Hermite grid.
// Only the terms of parity (r, s) enter G_rs, so each sum runs over every other order: a quarter
// of the first products' terms and half of the second's (the same sums as with the other
// orders' coefficients zeroed, less their zero terms).
void psf_transforms(const CartesianModel& psf, ConvolveWorkspace& ws) {
    const int n = psf.n_max;
    for (int r = 0; r < 2; ++r) ws.d_parity[r] = ws.d_psf(Eigen::seq(r, n, 2), Eigen::all);
    for (int s = 0; s < 2; ++s) {
        ws.g_part = psf.b(Eigen::all, Eigen::seq(s, n, 2));
        ws.psf_part.noalias() = ws.g_part * ws.d_parity[s];
        for (int r = 0; r < 2; ++r) {
            ws.g_part = ws.psf_part(Eigen::seq(r, n, 2), Eigen::all);
            ws.g_nodes[2 * r + s].noalias() = ws.d_parity[r].transpose() * ws.g_part;
        }
    }
}
}  // namespace

CartesianModel convolve(const CartesianModel& galaxy, const CartesianModel& psf,
                        ConvolveWorkspace& ws) {
    require_cartesian(galaxy, "convolve: galaxy");
    require_cartesian(psf, "convolve: psf");
    const int n_out = galaxy.n_max + psf.n_max;
    const double gamma = convolved_beta(galaxy.beta_pix, psf.beta_pix);
    const GaussHermite& rule = gauss_hermite(n_out + 1);
    signed_basis_at_nodes(rule, galaxy.beta_pix / gamma, galaxy.n_max, false, ws.d_galaxy);
    signed_basis_at_nodes(rule, psf.beta_pix / gamma, psf.n_max, false, ws.d_psf);
    // The projection depends on n_out alone: computed once per order a workspace meets.
    if (ws.projections.size() <= std::size_t(n_out)) ws.projections.resize(std::size_t(n_out) + 1);
    Eigen::MatrixXd& project = ws.projections[std::size_t(n_out)];
    if (project.size() == 0) signed_basis_at_nodes(rule, 1.0, n_out, true, project);
    // Galaxy transform on the node grid: F(i, j) = Σ f(n1, n2) D(n1, i) D(n2, j).
    ws.partial.noalias() = galaxy.b * ws.d_galaxy;
    ws.f_nodes.noalias() = ws.d_galaxy.transpose() * ws.partial;
    // H = Σ_{r,s} F reflected per (r, s) ∘ G_rs (see psf_transforms).
    psf_transforms(psf, ws);
    ws.h_nodes = ws.f_nodes.cwiseProduct(ws.g_nodes[0]);
    ws.h_nodes += ws.f_nodes.rowwise().reverse().cwiseProduct(ws.g_nodes[1]);
    ws.h_nodes += ws.f_nodes.colwise().reverse().cwiseProduct(ws.g_nodes[2]);
    ws.h_nodes += ws.f_nodes.reverse().cwiseProduct(ws.g_nodes[3]);
    // Project onto B_{l1} B_{l2} at γ: b_h = c_0² · Q H Qᵀ.
    CartesianModel out(galaxy.x, galaxy.y, gamma, n_out);
    const double c0 = tensor_constant(galaxy.beta_pix, psf.beta_pix, gamma);
    ws.partial.noalias() = ws.h_nodes * project.transpose();
    out.b.noalias() = (c0 * c0) * (project * ws.partial);
    clear_above_order(out.b, n_out);
    return out;
}

CartesianModel convolve(const CartesianModel& galaxy, const CartesianModel& psf) {
    ConvolveWorkspace ws;
    return convolve(galaxy, psf, ws);
}


ShapeletModel convolve(const ShapeletModel& galaxy, const ShapeletModel& psf) {
    require_scale(galaxy.beta_pix, "convolve: galaxy");
    require(galaxy.n_max >= 0 && int(galaxy.coeffs.size()) == polar_count(galaxy.n_max),
            "convolve: galaxy coefficients do not match n_max");
    return to_polar(convolve(to_cartesian(galaxy), to_cartesian(psf)));
}

Eigen::MatrixXd cartesian_convolution_matrix(const CartesianModel& psf, double galaxy_beta_pix,
                                             int n_max) {
    require_cartesian(psf, "cartesian_convolution_matrix: psf");
    require(n_max >= 0, "cartesian_convolution_matrix: n_max must be >= 0");
    const ConvolutionTensor c(galaxy_beta_pix, psf.beta_pix, n_max, psf.n_max);
    const int n_g = psf.n_max, n_out = c.n_out();
    // A[n](m, l) = C_{n m l};  Y[n2](m1, l2) = Σ_{m2} g(m1, m2) C_{n2 m2 l2}.
    std::vector<Eigen::MatrixXd> a(n_max + 1, Eigen::MatrixXd(n_g + 1, n_out + 1));
    for (int n = 0; n <= n_max; ++n)
        for (int m = 0; m <= n_g; ++m) a[n].row(m) = c.slice(m).row(n);
    std::vector<Eigen::MatrixXd> y(n_max + 1);
    for (int n2 = 0; n2 <= n_max; ++n2) y[n2].noalias() = psf.b * a[n2];
    // Column (n1, n2): L[(l1, l2)] = Σ_{m1} A[n1](m1, l1) Y[n2](m1, l2).
    Eigen::MatrixXd out = Eigen::MatrixXd::Zero(real_count(n_out), real_count(n_max));
    Eigen::MatrixXd block(n_out + 1, n_out + 1);
    for (int n1 = 0; n1 <= n_max; ++n1)
        for (int n2 = 0; n1 + n2 <= n_max; ++n2) {
            block.noalias() = a[n1].transpose() * y[n2];
            const int column = cartesian_index(n1, n2);
            for (int l1 = 0; l1 <= n_out; ++l1)
                for (int l2 = 0; l1 + l2 <= n_out; ++l2)
                    out(cartesian_index(l1, l2), column) = block(l1, l2);
        }
    return out;
}


Eigen::MatrixXd convolution_matrix(const ShapeletModel& psf, double galaxy_beta_pix, int n_max) {
    const Eigen::MatrixXd l =
        cartesian_convolution_matrix(to_cartesian(psf), galaxy_beta_pix, n_max);
    const int n_out = n_max + psf.n_max;
    return change_basis_rows(BasisChange::cartesian_to_real,
                             change_basis_columns(BasisChange::real_to_cartesian, l, n_max), n_out);
}

namespace {
// The 2-norm condition number of an upper-triangular R (= that of L = QR): the extreme
// eigenvalues of RᵀR by power iteration and inverse iteration (two triangular solves per step),
// O(n²) per step instead of the O(n³) of an SVD; at most 60 steps, fewer once both change by
// < 1e-6. Within 0.1% of the SVD value on the maps tested (a lower bound in exact arithmetic).
double condition_number_triangular(const Eigen::MatrixXd& r) {
    const auto upper = r.triangularView<Eigen::Upper>();
    if ((r.diagonal().array() == 0.0).any()) return std::numeric_limits<double>::infinity();
    const int n = int(r.cols());
    Eigen::VectorXd v = Eigen::VectorXd::LinSpaced(n, 1.0, 2.0).normalized(), w = v, z;
    double largest = 0.0, inverse_largest = 0.0;
    for (int step = 0; step < 60; ++step) {
        z = upper.transpose() * (upper * v);  // RᵀR v
        const double a = v.dot(z);
        v = z.normalized();
        z = upper.solve(upper.transpose().solve(w));  // (RᵀR)⁻¹ w
        const double b = w.dot(z);
        w = z.normalized();
        const bool done = std::abs(a - largest) <= 1e-6 * a &&
                          std::abs(b - inverse_largest) <= 1e-6 * b;
        largest = a;
        inverse_largest = b;
        if (done) break;
    }
    return std::sqrt(largest * inverse_largest);
}

// Least-squares solve of L x = y (full column rank: the map is injective,
// docs/algorithms.md#convolution) by Householder QR; fills the report.
Eigen::VectorXd solve_least_squares(const Eigen::MatrixXd& l, const Eigen::VectorXd& y,
                                    InverseReport& report) {
    require(l.cwiseAbs().maxCoeff() > 0.0, "deconvolve: the PSF is identically zero");
    const Eigen::HouseholderQR<Eigen::MatrixXd> qr(l);
    report.condition_number = condition_number_triangular(qr.matrixQR().topRows(l.cols()));
    const Eigen::VectorXd x = qr.solve(y);
    report.residual_norm = (l * x - y).norm();
    const double norm = y.norm();
    report.relative_residual = norm > 0.0 ? report.residual_norm / norm : 0.0;
    return x;
}
}  // namespace

ShapeletModel deconvolve(const ShapeletModel& observed, const ShapeletModel& psf, int n_max_out,
                         InverseReport* report) {
    const CartesianModel h = to_cartesian(observed);
    const CartesianModel g = to_cartesian(psf);
    require_cartesian(h, "deconvolve: observed");
    require_cartesian(g, "deconvolve: psf");
    require(n_max_out >= 0, "deconvolve: n_max_out must be >= 0");
    const double gamma = h.beta_pix, b = g.beta_pix;
    if (!(gamma > b))
        throw Error("deconvolve: observed beta " + std::to_string(gamma) +
                    " px must exceed the PSF beta " + std::to_string(b) + " px");
    const double alpha = std::sqrt((gamma - b) * (gamma + b));
    // Both sides in the packed Cartesian order (orthonormal: ‖·‖₂ is the image's L² norm),
    // zero-padded to the larger order; the order-by-order packing makes padding a suffix.
    const Eigen::MatrixXd l_map = cartesian_convolution_matrix(g, alpha, n_max_out);
    const int rows = real_count(std::max(n_max_out + g.n_max, h.n_max));
    Eigen::MatrixXd l = Eigen::MatrixXd::Zero(rows, l_map.cols());
    l.topRows(l_map.rows()) = l_map;
    Eigen::VectorXd y = Eigen::VectorXd::Zero(rows);
    y.head(real_count(h.n_max)) = pack_cartesian(h.b, h.n_max);
    InverseReport local;
    const Eigen::VectorXd x = solve_least_squares(l, y, report ? *report : local);
    CartesianModel out(observed.x, observed.y, alpha, n_max_out);
    out.b = unpack_cartesian(x, n_max_out);
    return to_polar(out);
}

DifferenceKernel difference_kernel(const ShapeletModel& old_psf, const ShapeletModel& new_psf,
                                   int n_max_kernel) {
    // k ∗ old = new is the deconvolution of new by old (convolution commutes).
    if (!(new_psf.beta_pix > old_psf.beta_pix))
        throw Error("difference_kernel: the new PSF's beta " + std::to_string(new_psf.beta_pix) +
                    " px must exceed the old PSF's " + std::to_string(old_psf.beta_pix) + " px");
    DifferenceKernel out;
    out.kernel = deconvolve(new_psf, old_psf, n_max_kernel, &out.report);
    return out;
}

}  // namespace shapesim
