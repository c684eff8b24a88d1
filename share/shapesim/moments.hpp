// Properties of a shapelet model straight from its coefficients: flux, centroid, second
// moments, rms radius, ellipticity and the L2 norm. All are exact (no image is drawn).
//
// Raw moments about the basis centre, z = x + iy in pixels from the centre, β in pixels
// (closed forms of Massey & Refregier 2005, MNRAS 363, 197, re-derived here for this
// repository's χ_{n,m} ∝ e^{+imθ}, hence the conjugates; with the Laguerre generating function
// Σ_q L_q^k(t) s^q = (1−s)^{−k−1} e^{−ts/(1−s)} each radial integral is one power series):
//   F     = ∫ f d²x        = 2√π β    Σ_{n even}      a_{n,0}
//   Z     = ∫ z f d²x      = 2√(2π) β² Σ_{n odd}      √(n+1) · conj a_{n,1}
//   R     = ∫ |z|² f d²x   = 4√π β³   Σ_{n even}      (n+1) · a_{n,0}
//   E     = ∫ z² f d²x     = 4√π β³   Σ_{n even ≥ 2}  √(n(n+2)) · conj a_{n,2}
// The Cartesian route is independent of those derivations: with M_p(n) = ∫ u^p φ_n du
// (`hermite_moments`),  ∫ x^p y^q f = β^{p+q+1} Σ b(n1,n2) M_p(n1) M_q(n2).  Both are provided;
// the unit tests hold them equal and equal to the moments of finely rendered images.
//
// Derived quantities (units: pixels, pixels², image units):
//   centroid offset   z̄ = Z / F                     (centroid = basis centre + z̄)
//   central moments   Q11 + Q22 = R/F − |z̄|²,  Q11 − Q22 + 2i Q12 = E/F − z̄²
//   rms radius        √(Q11 + Q22);  also R/F, the mean |z|² about the basis centre
//   distortion        χ = (Q11 − Q22 + 2i Q12)/(Q11 + Q22)   — the paper's e1 + i e2 (eqs. 6–7)
//                      and GalSim's "distortion" e; |χ| = (a² − b²)/(a² + b²)
//   reduced-shear ε   ε = χ / (1 + √(1 − |χ|²)) — GalSim's "reduced shear" g; |ε| = (a−b)/(a+b)
// a, b are the axes of the moment ellipse; the phase of χ and ε is 2θ, θ CCW from +x.
//
// Undefined values are NaN, never an exception (a catalogue of thousands must not stop at one
// odd object; writers refuse NaN fields, STYLE "JSON-lines"):
//   flux ≤ 0 or not finite  → every derived quantity is NaN (raw moments and flux are kept);
//   Q11 + Q22 ≤ 0           → rms radius, χ and ε are NaN;
//   |χ| ≥ 1 (Q not positive definite) → ε is NaN.
#pragma once

#include "shapesim/model.hpp"

namespace shapesim {

/// Raw moments about the basis centre (offsets in pixels; see the file comment).
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
