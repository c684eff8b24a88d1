// The polar shapelet basis χ_{n,m} (paper eq. 2) and the exact change of basis between polar
// and Cartesian coefficients.
//
//   χ_{n,m}(r, θ; β) = (−1)^q / (β √π) · [q!/p!]^{1/2} (r/β)^{|m|} L_q^{|m|}(r²/β²)
//                      · e^{−r²/2β²} e^{imθ}
// with q = (n − |m|)/2, p = (n + |m|)/2, θ counter-clockwise from +x (y up, FITS orientation).
// Within each order n, χ_{n,m} = Σ_{n1+n2=n} T^{(n)}_{m,n1} B_{n1}(x) B_{n2}(y), T^{(n)}
// unitary, cached per n. Evaluation and the ladder step: docs/algorithms.md#the-shapelet-basis
#pragma once

#include "shapesim/model.hpp"

#include <Eigen/Dense>

namespace shapesim {

/// χ_{n,m}(dx, dy; β) for the packed (n, m ≥ 0) up to n_max, at offset (dx, dy) in pixels from
/// the centre; out has polar_count(n_max) entries. (χ_{n,−m} = conj χ_{n,m}.)
void polar_basis(double dx, double dy, double beta_pix, int n_max, Complex* out);

/// Value of a polar model at a point (FITS pixel coordinates), unintegrated.
double evaluate(const ShapeletModel& model, double x, double y);

/// T^{(n)}: rows m = −n, −n+2, …, n; columns n1 = 0..n (n2 = n − n1). Unitary.
const Eigen::MatrixXcd& polar_cartesian_matrix(int n);

/// The change of basis between the real parameter vector (model.hpp) and packed Cartesian
/// coefficients (order n = 0..n_max, then n1 = 0..n) is block-diagonal by order n: both orders
/// put order n at offset n(n+1)/2 with n + 1 entries. `change_basis_block` is the (n+1)² block
/// (cached per n); the functions below apply the whole map block by block, O(n_max³) per column
/// instead of O(n_max⁴) dense (and never store a dense matrix: 28 MB at n_max 60).
enum class BasisChange { real_to_cartesian, cartesian_to_real };
const Eigen::MatrixXd& change_basis_block(BasisChange direction, int n);

/// B · X: rows of X (real_count(n_max) of them) mapped by the change of basis B.
Eigen::MatrixXd change_basis_rows(BasisChange direction, const Eigen::MatrixXd& x, int n_max);
/// X · B: columns of X (real_count(n_max) of them) mapped by B.
Eigen::MatrixXd change_basis_columns(BasisChange direction, const Eigen::MatrixXd& x, int n_max);

/// Index of b(n1, n2) in the packed Cartesian order used by the matrices above.
constexpr int cartesian_index(int n1, int n2) {
    return (n1 + n2) * (n1 + n2 + 1) / 2 + n1;
}

/// Exact conversions (same centre and β).
CartesianModel to_cartesian(const ShapeletModel& model);
ShapeletModel to_polar(const CartesianModel& model);

/// Pack/unpack a Cartesian matrix b(n1, n2) into the packed Cartesian vector.
Eigen::VectorXd pack_cartesian(const Eigen::MatrixXd& b, int n_max);
Eigen::MatrixXd unpack_cartesian(const Eigen::VectorXd& packed, int n_max);

}  // namespace shapesim
