// The reference shear estimator: adaptive moments with the linear PSF correction (Bernstein &
// Jarvis 2002, AJ 123, 583, §3 and App. C; Hirata & Seljak 2003, MNRAS 343, 459, §2.1–2.3;
// GalSim's hsm "LINEAR" method is this idea, and re-Gaussianization builds on it).
//
// Adaptive moments: the elliptical Gaussian weight W(x) = exp(−½ (x−x0)ᵀ M⁻¹ (x−x0)) that
// matches the object. Each pass takes the W-weighted centroid offset Δ and covariance C about
// it, and sets x0 ← x0 + 2Δ, M ← 2C: for a Gaussian object of covariance Σ at μ the product
// with W is a Gaussian of covariance (Σ⁻¹ + M⁻¹)⁻¹, so the fixed point is M = Σ, x0 = μ — the
// adaptive moments of a Gaussian are its own. Stopped when the centre moves < 1e-7 pixel and
// M by < 1e-8 relatively; failed when M stops being positive definite, leaves the image, or
// after 200 passes.
//
// Linear PSF correction: for a Gaussian galaxy seen through a Gaussian PSF the covariances
// add, so Σ_gal = M_obs − M_psf exactly; from it χ = (Σ11 − Σ22 + 2iΣ12)/(Σ11 + Σ22) and the
// shear estimate ε = χ/(1 + √(1 − |χ|²)), whose mean over an isotropic population is the
// reduced shear g (responsivity 1). Resolution R = 1 − T_psf/T_obs (T = M11 + M22): 0 for an
// unresolved object, → 1 for a large one. Real galaxies and PSFs are not Gaussian: their
// adaptive moments weight the core, so the correction leaves a bias that grows as R falls —
// what a calibration measures (re-Gaussianization would correct part of it; not built).
#pragma once

#include "shapesim/image.hpp"
#include "shapesim/lsq.hpp"
#include "shapesim/model.hpp"

#include <optional>
#include <string>

namespace shapesim {

struct AdaptiveMoments {
    double x = 0.0, y = 0.0;            ///< centre, 0-based pixel coordinates of the image
    double m11 = 0.0, m22 = 0.0, m12 = 0.0;  ///< the matched weight's covariance, pixels²
    int iterations = 0;
    double trace() const { return m11 + m22; }
};

/// The adaptive moments of `image` (background subtracted) from a start at (x0, y0) (0-based)
/// with a round weight of `sigma0` pixels; pixels where `mask` is non-zero (when given) are
/// left out. nullopt, with `why` set, when they do not converge (see the file comment).
std::optional<AdaptiveMoments> adaptive_moments(const ImageArray& image, const MaskArray* mask,
                                                double x0, double y0, double sigma0,
                                                std::string* why = nullptr);

/// A PSF-corrected shear estimate.
struct ShearEstimate {
    Complex epsilon;          ///< ε = e1 + i e2 of Σ_gal = M_obs − M_psf
    double resolution = 0.0;  ///< R = 1 − T_psf/T_obs
};

/// ε from the object's and the PSF's adaptive moments; nullopt when Σ_gal is not positive
/// definite (an object no larger than the PSF).
std::optional<ShearEstimate> linear_shear_estimate(const AdaptiveMoments& object,
                                                   const AdaptiveMoments& psf);

/// The adaptive moments of a unit-flux model (a PSF, field pixels) drawn pixel-integrated,
/// centred on a pixel: what an image's point source gives.
AdaptiveMoments psf_adaptive_moments(const ShapeletModel& psf);

}  // namespace shapesim
