// The 1D Cartesian shapelet (Hermite-function) basis, its pixel integrals, and Gauss–Hermite
// quadrature — the root of every exact formula in shapesim.
//
// Dimensionless basis (DESIGN §3; Refregier 2003 eq. 1):
//   φ_0(u) = π^{-1/4} e^{-u²/2},  φ_1(u) = √2 u φ_0(u),
//   φ_{n+1}(u) = √(2/(n+1)) u φ_n(u) − √(n/(n+1)) φ_{n−1}(u).
// Scaled: B_n(x; β) = β^{-1/2} φ_n(x/β), orthonormal on the real line.
// H_n and n! are never formed; the recurrence runs on φ_n e^{u²/2} with rescaling, so values
// stay finite (and underflow gracefully to 0) for any n and |u|.
//
// Pixel integrals I_n = ∫_{u_a}^{u_b} φ_n du (DESIGN §3):
//   I_0 = π^{-1/4} √(π/2) [erf(u/√2)],  I_1 = −√2 [φ_0],
//   I_{n+1} = √(n/(n+1)) I_{n−1} − √(2/(n+1)) [φ_n],      with [g] = g(u_b) − g(u_a).
#pragma once

#include <Eigen/Dense>
#include <vector>

namespace shapesim {

/// φ_0(u) … φ_{n_max}(u) into out[0..n_max].
void hermite_functions(double u, int n_max, double* out);

/// I_n = ∫_{u_a}^{u_b} φ_n(u) du for n = 0..n_max into out[0..n_max].
void hermite_integrals(double u_a, double u_b, int n_max, double* out);

/// Basis B_n(x; β) sampled at pixel centres: column i is x = first_offset + i (pixels from the
/// model centre), row n = 0..n_max. Returns an (n_max+1) × npix matrix.
Eigen::MatrixXd sampled_basis_1d(int n_max, double beta_pix, double first_offset, int npix);

/// Basis B_n(x; β) integrated over unit pixels: column i covers
/// [first_offset + i − ½, first_offset + i + ½] (pixels from the model centre), row n.
/// Adjacent pixels share their edge values, so the columns sum to ∫ over the whole span.
/// Cost O(n_max · npix); returns an (n_max+1) × npix matrix.
Eigen::MatrixXd pixel_basis_1d(int n_max, double beta_pix, double first_offset, int npix);

/// In-place variant of pixel_basis_1d for hot loops: `out` must be (n_max+1) × npix and
/// `edges` (n_max+1) × (npix+1) scratch (caller-owned, so a loop allocates nothing).
void pixel_basis_1d(int n_max, double beta_pix, double first_offset, int npix,
                    Eigen::Ref<Eigen::MatrixXd> out, Eigen::Ref<Eigen::MatrixXd> edges);

/// K-point Gauss–Hermite rule in "Hermite-function" form: for any polynomial p of degree
/// ≤ 2K−1,  ∫ p(u) e^{-u²} du = Σ_i weights[i] · p(nodes[i]) e^{-nodes[i]²}  exactly.
/// Equivalently the weights are W_i = 1 / Σ_{k<K} φ_k(u_i)², which never overflow, so the
/// rule integrates any product of Hermite functions of total order ≤ 2K−1 exactly.
struct GaussHermite {
    std::vector<double> nodes;    ///< ascending roots of φ_K
    std::vector<double> weights;  ///< W_i (see above), all positive
};

/// The K-point rule (K ≥ 1), computed once (Golub–Welsch, then Newton-polished) and cached;
/// thread-safe, the reference stays valid for the life of the program.
const GaussHermite& gauss_hermite(int k);

/// M_p(n) = ∫ u^p φ_n(u) du for p = 0..p_max, n = 0..n_max: a (p_max+1) × (n_max+1) matrix.
/// Closed form by the ladder relations (M_0(n+1) = √(n/(n+1)) M_0(n−1), and
/// u φ_n = √((n+1)/2) φ_{n+1} + √(n/2) φ_{n−1}). Used for moments from coefficients.
Eigen::MatrixXd hermite_moments(int p_max, int n_max);

}  // namespace shapesim
