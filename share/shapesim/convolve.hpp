// Exact shapelet convolution, deconvolution and the PSF "difference kernel" (Refregier 2003
// §3.3; Refregier & Bacon 2003 §3; Massey et al. 2004 §2.3; DESIGN §3).
// Plain convolution in pixels, no implicit normalisation: h(x) = ∫ f(x′) g(x − x′) d²x′,
// flux_h = flux_f · flux_g; g about its own centre, h at the galaxy's. f of scale α and order
// N_f through g of scale b and order N_g is exactly a shapelet series of scale
// γ = √(α² + b²) and order N_f + N_g. Deconvolution is the least-squares inverse at
// α = √(γ² − b²), unique for γ > b; its condition number is reported.
// Derivation: docs/algorithms.md#convolution
#pragma once

#include "shapesim/model.hpp"

#include <Eigen/Dense>
#include <vector>

namespace shapesim {

/// γ = √(α² + b²): the scale of a series of scale α convolved with one of scale b (pixels).
double convolved_beta(double alpha, double b);

/// The 1D convolution tensor C_{nml} for scales (α, b), orders n ≤ n_f, m ≤ n_g, l ≤ n_f + n_g.
/// Exact to rounding (Gauss–Hermite with K = n_f + n_g + 1 nodes). Cost O(K · n_f · n_g · K).
class ConvolutionTensor {
public:
    /// @param alpha scale of the first factor (pixels, > 0); @param b scale of the second
    /// @param n_f, n_g orders of the two factors (≥ 0)
    ConvolutionTensor(double alpha, double b, int n_f, int n_g);

    double alpha() const { return alpha_; }
    double b() const { return b_; }
    double gamma() const { return gamma_; }
    int n_f() const { return n_f_; }
    int n_g() const { return n_g_; }
    int n_out() const { return n_f_ + n_g_; }

    /// C_{nml}: 0 ≤ n ≤ n_f, 0 ≤ m ≤ n_g, 0 ≤ l ≤ n_out (unchecked).
    double operator()(int n, int m, int l) const { return slices_[m](n, l); }
    /// The slice C_{n m ·} for fixed m: an (n_f+1) × (n_out+1) matrix.
    const Eigen::MatrixXd& slice(int m) const { return slices_[m]; }

private:
    double alpha_, b_, gamma_;
    int n_f_, n_g_;
    std::vector<Eigen::MatrixXd> slices_;
};

/// Reusable buffers for `convolve` in a loop over many galaxies (one per thread).
struct ConvolveWorkspace {
    Eigen::MatrixXd d_galaxy, d_psf;            // basis at the Gauss–Hermite nodes
    std::vector<Eigen::MatrixXd> projections;   // by n_out (empty until met): the weighted basis
    Eigen::MatrixXd partial, f_nodes, h_nodes;  // transforms on the node grid
    Eigen::MatrixXd g_nodes[4], g_part, psf_part, d_parity[2];
};

/// Exact convolution of Cartesian series: scale γ, n_max galaxy.n_max + psf.n_max, centred at
/// the galaxy's centre. Cost O(K N_f² + K² N) for K = N + 1 (docs/algorithms.md#convolution).
CartesianModel convolve(const CartesianModel& galaxy, const CartesianModel& psf,
                        ConvolveWorkspace& workspace);
CartesianModel convolve(const CartesianModel& galaxy, const CartesianModel& psf);

/// Exact convolution of polar series (through the Cartesian form and back, both exact).
ShapeletModel convolve(const ShapeletModel& galaxy, const ShapeletModel& psf);

/// The convolution as a linear map in the packed Cartesian order (polar.hpp
/// `cartesian_index`): a real_count(n_max + psf.n_max) × real_count(n_max) matrix L with
/// pack(b_h) = L · pack(b_f) for any galaxy of scale `galaxy_beta_pix` and order `n_max`.
Eigen::MatrixXd cartesian_convolution_matrix(const CartesianModel& psf, double galaxy_beta_pix,
                                             int n_max);

/// The convolution as a linear map of real parameter vectors (model.hpp): a
/// real_count(n_max + psf.n_max) × real_count(n_max) matrix M with
/// real_parameters(convolve(f, psf)) = M · real_parameters(f) for every f of scale
/// `galaxy_beta_pix` and order `n_max`. For fitting PSF-convolved models: design matrix
/// = (pixel-integrated basis at γ, in real-parameter form) · M.
Eigen::MatrixXd convolution_matrix(const ShapeletModel& psf, double galaxy_beta_pix, int n_max);

/// How well a least-squares inverse (deconvolution, difference kernel) fits.
struct InverseReport {
    double residual_norm = 0.0;      ///< ‖g ∗ f̂ − h‖₂ (L² norm of the image, pixel units)
    double relative_residual = 0.0;  ///< residual_norm / ‖h‖₂ (0 when h = 0)
    double condition_number = 0.0;   ///< σ_max/σ_min of the map (power-iteration estimate)
};

/// Least-squares deconvolution: the series f̂ of scale β_out = √(γ² − b²) and order n_max_out
/// minimising ‖psf ∗ f̂ − observed‖₂, centred at the observed centre. Throws Error unless
/// γ > b (γ = observed.beta_pix, b = psf.beta_pix), n_max_out ≥ 0 and the PSF is nonzero.
/// Exact (to rounding × condition number) when observed = psf ∗ f with n_max(f) ≤ n_max_out.
ShapeletModel deconvolve(const ShapeletModel& observed, const ShapeletModel& psf, int n_max_out,
                         InverseReport* report = nullptr);

/// A difference kernel k with k ∗ old_psf ≈ new_psf (Massey et al. 2004 §2.3: keep the old PSF
/// through the simulation, re-observe with a broader one at the end). k has scale
/// √(β_new² − β_old²), order n_max_kernel and the new PSF's centre; it is the least-squares
/// deconvolution of new by old. `report.relative_residual` says how well any kernel of that
/// order can do (0 when new = k ∗ old exactly); a large value flags a new PSF that is not
/// broader than the old one in every direction. Throws Error unless β_new > β_old.
struct DifferenceKernel {
    ShapeletModel kernel;
    InverseReport report;
};
DifferenceKernel difference_kernel(const ShapeletModel& old_psf, const ShapeletModel& new_psf,
                                   int n_max_kernel);

}  // namespace shapesim
