// Geometric transforms of a shapelet model, each with its accuracy stated.
//
// Frame: offsets in pixels from the model's basis centre c (FITS pixels), θ counter-clockwise
// from +x with y up, χ_{n,m} ∝ e^{imθ} (polar.hpp). f(u) below is the input model as a function
// of the offset u from its centre.
//
// EXACT (coefficients only, to rounding; Massey & Refregier 2005, MNRAS 363, 197; DESIGN §3):
//   rotation by ρ about c        f(R(−ρ)u)     a_{n,m} → a_{n,m} e^{−imρ}
//   reflection, axis ∥ x         f(x, −y)      a_{n,m} → conj a_{n,m}   (= a_{n,−m})
//   reflection, axis at angle ψ  f(S_ψ u)      a_{n,m} → conj(a_{n,m}) e^{−2imψ}
//                                (S_ψ = R(ψ) diag(1,−1) R(−ψ); ψ = 0 is the case above)
//   dilation by s about c        f(u/s)/s²     β → sβ, a → a/s  (flux kept; f(u/s): a → s·a)
//
// PROJECTED (exact to a stated order, error reported): for a 2×2 matrix A and shift d (pixels)
//   g(X) = f(A⁻¹(X − c − d))            (X in FITS pixels; A acts about the model centre)
// is expanded on the Cartesian basis of an output frame (centre c_o, scale β_o, order N):
//   b_o(l1, l2) = ∫ B_{l1}(X−c_o; β_o) B_{l2}(Y−c_o; β_o) g(X) d²X
//               = |det A| ∫ B_l(A u + e; β_o) f(u) d²u,        e = c + d − c_o.
// Each integrand is a polynomial of total degree ≤ N + n_in times exp(−½ uᵀQu − hᵀu),
// Q = AᵀA/β_o² + I/β², h = Aᵀe/β_o². Completing the square (u* = −Q⁻¹h) and diagonalising
// Q = V diag(λ) Vᵀ, u = u* + V diag(√(2/λ)) t turns it into p(t) e^{−|t|²}; the K×K tensor
// Gauss–Hermite rule with K = ⌊(N + n_in)/2⌋ + 1 (exact to degree 2K−1 per axis,
// basis1d.hpp) integrates it EXACTLY. Coefficients up to order N are therefore exact to
// rounding; the only error is the truncation at N, computed exactly by Parseval (the output
// basis is orthonormal):
//   ‖g‖² = ∫ f(A⁻¹(X−c−d))² d²X = |det A| ‖f‖²      (substitute X = c + d + A u),
//   truncation error  ‖g − P_N g‖² = ‖g‖² − Σ_{l1+l2 ≤ N} b_o(l1,l2)²  ≥ 0.
// It is absolute (image units² × pixel²); its relative form divides by ‖g‖². Rounding limits
// it to a floor of ~1e-15·‖g‖², so tolerances below 1e-14 are refused. The pointwise image
// error is bounded through it: for any pixel, |∫_pixel (g − P_N g)| ≤ √(truncation error).
// Moments of P_N g (flux, centroid, Q; moments.hpp) are inner products with 1, x, x², so their
// relative errors are of order √(relative error) (the tests hold them within 10×). The exact
// transformed moments need no projection: flux × |det A|, centroid c + d + A z̄, Q → A Q Aᵀ.
//
// Automatic order: with ProjectionOptions::n_out < 0, N is the smallest order whose relative
// truncation error is ≤ tolerance (searched up to n_out_max; the coefficients of order ≤ N do
// not depend on N, so one projection at a larger trial order serves every smaller N).
//
// Shear and lensing follow GalSim (GalSim-developers/GalSim, galsim/shear.py Shear.getMatrix,
// galsim/gsobject.py GSObject.shear, .lens, .transform): a position x of the object moves to
// A x, and surface brightness is carried along, g(x) = f(A⁻¹x).
//   shear(g1, g2):  A = S(g) = [[1+g1, g2], [g2, 1−g1]] / √(1−|g|²), det S = 1 (area and flux
//                   kept). A round object becomes an ellipse with (a−b)/(a+b) = |g| and major
//                   axis at ½ arg(g1 + i g2); its moment ellipticity ε equals g (moments.hpp).
//   lens(g1, g2, κ): the lens equation maps the image-plane offset θ to the source plane
//                   𝒜θ, 𝒜 = (1−κ)[[1−g1, −g2], [−g2, 1+g1]], so A = 𝒜⁻¹ = √μ S(g) with
//                   magnification μ = 1/det 𝒜 = 1/((1−κ)²(1−|g|²)); this is GalSim
//                   obj.lens(g1, g2, μ) (flux × μ). By default the result is divided by μ
//                   (flux conserved: GalSim obj.lens(g1, g2, μ).withScaledFlux(1/μ)).
// The general affine_transform keeps surface brightness (flux × |det A|), like GalSim transform.
#pragma once

#include "shapesim/model.hpp"

#include <Eigen/Dense>

namespace shapesim {

/// The object rotated by ρ radians counter-clockwise about its basis centre (exact).
ShapeletModel rotate(const ShapeletModel& model, double rho);

/// The object rotated by ρ radians counter-clockwise about the point (x0, y0) in FITS pixels:
/// the phases as in rotate(), and the centre moves to p + R(ρ)(c − p), p = (x0, y0) (exact).
ShapeletModel rotate_about(const ShapeletModel& model, double rho, double x0, double y0);

/// Mirror image about the line through the basis centre parallel to the x axis (exact).
ShapeletModel reflect_x(const ShapeletModel& model);

/// Mirror image about the line through the basis centre at angle ψ radians counter-clockwise
/// from +x (exact): a_{n,m} → conj(a_{n,m}) e^{−2imψ}.
ShapeletModel reflect(const ShapeletModel& model, double psi);

/// The object dilated by `scale` > 0 about its centre (exact): β → scale·β. With
/// conserve_flux (default) the coefficients are divided by scale (GalSim `dilate`); without,
/// they are multiplied by it: surface brightness kept, flux × scale² (GalSim `expand`).
ShapeletModel dilate(const ShapeletModel& model, double scale, bool conserve_flux = true);

/// Accuracy of a projection.
struct ProjectionOptions {
    /// Output order N; < 0 (default) chooses the smallest N whose relative truncation error
    /// is ≤ tolerance.
    int n_out = -1;
    /// Target relative truncation error ‖g − P_N g‖² / ‖g‖² for the automatic order; ≥ 1e-14.
    double tolerance = 1e-10;
    /// Largest order the automatic search may reach (then `tolerance_met` is false).
    int n_out_max = 60;
};

/// The output basis of a projection.
struct OutputBasis {
    double x = 0.0, y = 0.0;  ///< centre c_o, FITS pixels
    double beta_pix = 1.0;    ///< β_o, pixels
};

/// A projected model and the error it bought (see the file comment).
struct Projection {
    ShapeletModel model;            ///< the projection P_N g, n_max = N
    double norm2 = 0.0;             ///< ‖g‖², exact
    double truncation_error = 0.0;  ///< ‖g − P_N g‖² (absolute, clamped at 0)
    double relative_error = 0.0;    ///< truncation_error / ‖g‖² (0 when g = 0)
    bool tolerance_met = true;      ///< relative_error ≤ options.tolerance
};

/// Reusable buffers so that projecting many models does not allocate in the hot loop.
struct ProjectionWorkspace {
    Eigen::MatrixXd in_x, in_y, out_x, out_y, partial, b_out;
    Eigen::VectorXd values;
};

/// g(X) = f(A⁻¹(X − c − d)) projected onto `basis` (the general routine; file comment).
/// @param a      the 2×2 matrix A, finite, det A ≠ 0
/// @param shift  d in pixels
/// @param workspace  reusable buffers, or nullptr to allocate
Projection project_affine(const ShapeletModel& model, const Eigen::Matrix2d& a,
                          const Eigen::Vector2d& shift, const OutputBasis& basis,
                          const ProjectionOptions& options = {},
                          ProjectionWorkspace* workspace = nullptr);

/// project_affine with the default output basis: centre c + d, β_o = β √|det A|
/// (surface brightness kept: flux × |det A|).
Projection affine_transform(const ShapeletModel& model, const Eigen::Matrix2d& a,
                            const Eigen::Vector2d& shift, const ProjectionOptions& options = {},
                            ProjectionWorkspace* workspace = nullptr);

/// The object moved by (dx, dy) pixels while the basis centre and β stay where they are.
/// (To move a model exactly, change its x, y instead; this re-expands it about a fixed centre.)
Projection translate(const ShapeletModel& model, double dx, double dy,
                     const ProjectionOptions& options = {},
                     ProjectionWorkspace* workspace = nullptr);

/// The same image expanded about a new basis centre (x, y) in FITS pixels, same β.
Projection recentre(const ShapeletModel& model, double x, double y,
                    const ProjectionOptions& options = {},
                    ProjectionWorkspace* workspace = nullptr);

/// The same image expanded with another scale β_o = beta_pix (pixels), same centre.
Projection change_beta(const ShapeletModel& model, double beta_pix,
                       const ProjectionOptions& options = {},
                       ProjectionWorkspace* workspace = nullptr);

/// GalSim's shear matrix S(g) = [[1+g1, g2], [g2, 1−g1]] / √(1−|g|²); requires |g| < 1.
Eigen::Matrix2d shear_matrix(double g1, double g2);

/// The object sheared by reduced shear (g1, g2), |g| < 1, about its centre: A = S(g), same
/// centre and β (area, flux and surface brightness kept; GalSim `shear`).
Projection shear(const ShapeletModel& model, double g1, double g2,
                 const ProjectionOptions& options = {},
                 ProjectionWorkspace* workspace = nullptr);

/// Weak-lensing distortion: reduced shear (g1, g2), convergence κ.
struct Lensing {
    double g1 = 0.0, g2 = 0.0;  ///< reduced shear g = γ/(1−κ), |g| < 1
    double kappa = 0.0;         ///< convergence κ < 1
    bool conserve_flux = true;  ///< divide by μ (true) or keep surface brightness (false)
};

/// A = 𝒜⁻¹ = [[1+g1, g2], [g2, 1−g1]] / ((1−κ)(1−|g|²)) — the image of a source-plane offset.
Eigen::Matrix2d lensing_matrix(const Lensing& lensing);
/// Magnification μ = 1/((1−κ)²(1−|g|²)).
double magnification(const Lensing& lensing);

/// The object lensed about its centre: A = lensing_matrix, centre kept, β_o = β √μ; divided
/// by μ when conserve_flux (GalSim `lens(g1, g2, μ)`, then flux rescaled).
Projection lens(const ShapeletModel& model, const Lensing& lensing,
                const ProjectionOptions& options = {},
                ProjectionWorkspace* workspace = nullptr);

}  // namespace shapesim
