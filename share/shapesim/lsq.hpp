// Weighted linear least-squares shapelet decomposition of a pixel stamp (DESIGN §3): at a
// given centre, β and n_max, minimise χ² = Σ_p w_p (I_p − Σ_k A_{pk} c_k)² with A the
// pixel-integrated basis, on the separable Cartesian basis, then map to polar exactly. Solved
// by the separable normal equations (LDLT) when well conditioned, else by pivoting QR of
// W^{1/2}A. A pixel counts when its weight is > 0 and finite, its value finite and the mask 0;
// weights are inverse variances in the image's units.
// Derivation: docs/algorithms.md#least-squares-fits
#pragma once

#include "shapesim/correlation.hpp"
#include "shapesim/image.hpp"
#include "shapesim/model.hpp"

#include <Eigen/Dense>
#include <cstdint>

namespace shapesim {

/// Per-pixel mask, same shape as the image: non-zero excludes the pixel (e.g. a neighbour's).
using MaskArray = Eigen::Array<std::uint8_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// Which solver to use (docs/algorithms.md); `automatic` picks `normal` when well-conditioned.
enum class LsqSolver { automatic, normal, qr };

/// What a decomposition returns.
struct ShapeletFit {
    ShapeletModel model;          ///< polar coefficients at the requested centre, β, n_max
    Eigen::MatrixXd covariance;   ///< of the real parameter vector (model.hpp order)
    double chi2 = 0.0;            ///< Σ w (data − model)² over used pixels
    double chi2r = 0.0;           ///< chi2 / dof
    long pixels_used = 0;
    long dof = 0;                 ///< pixels_used − real_count(n_max)
    ImageArray model_image;       ///< pixel-integrated model over the whole stamp
    ImageArray residual;          ///< image − model (NaN where the image is not finite)
    LsqSolver solver_used = LsqSolver::automatic;

    /// 1σ errors of the real parameter vector.
    Eigen::VectorXd errors() const { return covariance.diagonal().cwiseSqrt(); }
};

/// Fit a shapelet model to `image` with inverse-variance `weight` (same shape), optional
/// `mask`, centre (x, y) in the stamp's FITS pixel coordinates, scale beta_pix and n_max.
/// Throws Error when shapes differ, a weight is negative or infinite, β ≤ 0, there are fewer
/// usable pixels than coefficients, or the design is rank-deficient (basis not constrained).
ShapeletFit fit_shapelets(const ImageArray& image, const ImageArray& weight,
                          const MaskArray* mask, double x, double y, double beta_pix, int n_max,
                          LsqSolver solver = LsqSolver::automatic);

/// Forward modelling through a PSF (the stable form of the paper's §2.3 deconvolution): the
/// *intrinsic* model of scale beta_pix and order n_max whose convolution with `psf` (unit
/// flux, field pixels; convolve.hpp) best fits the image. The design matrix is the
/// pixel-integrated basis at γ = √(β² + b²), order n_max + psf.n_max, times the exact
/// convolution map (convolve.hpp cartesian_convolution_matrix), so the unknowns stay the
/// intrinsic coefficients. `model`, `covariance` and `dof` are the intrinsic model's;
/// `model_image`, `residual` and χ² are of its convolution, what the data are compared with.
ShapeletFit fit_convolved_shapelets(const ImageArray& image, const ImageArray& weight,
                                    const MaskArray* mask, double x, double y, double beta_pix,
                                    int n_max, const CartesianModel& psf,
                                    LsqSolver solver = LsqSolver::automatic);

/// The best multiple of one fixed shape: the model a·`shape` (its coefficients and β_pix; its
/// centre replaced by (x, y)), seen through `psf` when given (intrinsic, as
/// fit_convolved_shapelets), a the one linear unknown. `model` is a·shape, `covariance` that
/// of its real parameters (Var a times the shape's outer product), `dof` pixels − 1; images and
/// χ² as the other fits'. For a family of shapes searched outside (decompose's elliptical
/// Gaussians). Throws Error as fit_shapelets, or when the shape leaves no light on the pixels.
ShapeletFit fit_shape_amplitude(const ImageArray& image, const ImageArray& weight,
                                const MaskArray* mask, double x, double y,
                                const ShapeletModel& shape, const CartesianModel* psf = nullptr);

/// The χ² a fit takes up from correlated noise: fit_shapelets at (x, y, β, n_max), or
/// fit_convolved_shapelets through `psf`, on noise whose pixel-to-pixel correlation is `xi`
/// (in units of each pixel's own variance) leaves E[χ²] = N − T with
///     T = tr((BᵀB)⁻¹ BᵀRB),
/// B the weighted design W^{1/2}A over the pixels the fit uses (same rule, same Errors) and
/// R_{pq} = ξ(p − q). White noise gives T = p, the coefficients' count. Decompose's rule
/// T ≈ p·F² holds for a basis smoother than the correlation (and for the HDF's short drizzle
/// correlation); for smoothly correlated noise (PSF-matched images) the higher orders, whose
/// oscillations are as fine as the correlation, take up much less: on Gaussian-correlated
/// noise of F² = 9.5 about 6 per coefficient at n_max 4 and 4 at n_max 12 (β 2.5 pixels).
/// Cost: one correlation of each of the design's columns, O(p · N · (2·radius + 1)²).
double noise_take_up(const ImageArray& image, const ImageArray& weight, const MaskArray* mask,
                     double x, double y, double beta_pix, int n_max, const NoiseCorrelation& xi,
                     const CartesianModel* psf = nullptr);

}  // namespace shapesim
