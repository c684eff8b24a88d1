// Properties of a shapelet model straight from its coefficients: flux, centroid, second
// moments, rms radius, ellipticity and the L2 norm, all exact (no image is drawn; Massey &
// Refregier 2005). Units: pixels, pixels², image units; z = x + iy from the basis centre.
//   F = 2√π β Σ_{n even} a_{n,0},   χ = (Q11 − Q22 + 2i Q12)/(Q11 + Q22) (paper eqs. 6–7),
//   ε = χ / (1 + √(1 − |χ|²)) (GalSim's reduced shear g).
// Undefined values are NaN, never an exception: flux ≤ 0 or not finite makes every derived
// quantity NaN; Q11 + Q22 ≤ 0 the rms radius, χ and ε; |χ| ≥ 1 ε.
// Derivation: docs/algorithms.md#moments
#pragma once

#include "shapesim/model.hpp"

namespace shapesim {

/// Raw moments about the basis centre (offsets in pixels; docs/algorithms.md#moments).
struct RawMoments {
    double flux = 0.0;  ///< F = ∫ f d²x, image units
    Complex z;          ///< Z = ∫ (x + iy) f d²x
    double r2 = 0.0;    ///< R = ∫ (x² + y²) f d²x
    Complex z2;         ///< E = ∫ (x + iy)² f d²x
};

/// Flux, centroid, second moments and ellipticities (units and NaN rules: file comment).
struct Moments {
    double flux = 0.0;              ///< ∫ f d²x, image units
    double dx = 0.0, dy = 0.0;      ///< centroid − basis centre, pixels
    double x = 0.0, y = 0.0;        ///< centroid, FITS pixel coordinates
    double q11 = 0.0, q22 = 0.0;    ///< central second moments ⟨(x−x̄)²⟩, ⟨(y−ȳ)²⟩, pixels²
    double q12 = 0.0;               ///< ⟨(x−x̄)(y−ȳ)⟩, pixels²
    double r2_about_centre = 0.0;   ///< ⟨(x−x_c)² + (y−y_c)²⟩ about the basis centre, pixels²
    double rms_radius = 0.0;        ///< √(Q11 + Q22), pixels
    Complex chi;                    ///< distortion (Q11 − Q22 + 2i Q12)/(Q11 + Q22)
    Complex epsilon;                ///< reduced-shear ellipticity χ/(1 + √(1 − |χ|²))
};

/// F = 2√π β Σ_{n even} a_{n,0} (image units; DESIGN §2). O(n_max).
double flux(const ShapeletModel& model);

/// ‖f‖² = ∫ f² d²x = Σ_n [a_{n,0}² + 2 Σ_{m>0} |a_{n,m}|²] (orthonormality; image units²·px²).
double squared_norm(const ShapeletModel& model);
/// ‖f‖² = Σ b(n1, n2)² for a Cartesian model.
double squared_norm(const CartesianModel& model);

/// Raw moments by the polar closed forms; O(n_max).
RawMoments raw_moments(const ShapeletModel& model);
/// Raw moments by the Cartesian route (hermite_moments); O(n_max²).
RawMoments raw_moments(const CartesianModel& model);

/// Derived moments from raw moments about a basis centre (x_c, y_c) in FITS pixels.
Moments moments_from_raw(const RawMoments& raw, double x_c, double y_c);

/// All moments of a model (polar closed forms).
Moments moments(const ShapeletModel& model);
/// All moments of a Cartesian model (Cartesian route).
Moments moments(const CartesianModel& model);

}  // namespace shapesim
