// Geometric transforms of a shapelet model, each with its accuracy stated (DESIGN §3). Frame:
// pixels from the basis centre, θ counter-clockwise from +x, χ_{n,m} ∝ e^{imθ} (polar.hpp).
// EXACT, coefficients only (Massey & Refregier 2005): rotation by ρ a_{n,m} → a_{n,m} e^{−imρ};
// reflection about x a → conj a; dilation by s β → sβ, a → a/s (flux kept).
// PROJECTED: g(X) = f(A⁻¹(X − c − d)) on an output basis of order N, exact to rounding by
// Gauss–Hermite quadrature, its truncation error ‖g − P_N g‖² exact by Parseval. Shear and
// lensing follow GalSim: A = S(g) = [[1+g1, g2], [g2, 1−g1]] / √(1−|g|²); lens A = √μ S(g).
// Derivation: docs/algorithms.md#transforms
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

/// A projected model and the error it bought (docs/algorithms.md#transforms).
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

/// g(X) = f(A⁻¹(X − c − d)) projected onto `basis` (the general routine;
/// docs/algorithms.md#transforms).
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
