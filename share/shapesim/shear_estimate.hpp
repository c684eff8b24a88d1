// The reference shear estimator: adaptive moments with the linear PSF correction (Bernstein &
// Jarvis 2002, §3 and App. C; Hirata & Seljak 2003, §2.1–2.3; GalSim's hsm "LINEAR"):
//   Σ_gal = M_obs − M_psf,  χ = (Σ11 − Σ22 + 2iΣ12)/(Σ11 + Σ22),  ε = χ/(1 + √(1 − |χ|²)),
// whose mean over an isotropic population is the reduced shear g; resolution
// R = 1 − T_psf/T_obs (T = M11 + M22). Exact for Gaussians; real galaxies keep a bias that
// grows as R falls.
// Derivation: docs/algorithms.md#shear-estimation
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
/// left out. nullopt, with `why` set, when they do not converge
/// (docs/algorithms.md#shear-estimation).
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
