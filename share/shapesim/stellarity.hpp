// Stellarity: the probability that a detection is a point source, from how concentrated it
// is compared with the PSF (libsep has no CLASS_STAR; this replaces it). The statistic is the
// core fraction ρ = F(0.6 FWHM_psf)/F(2 FWHM_psf) in circular apertures: a star's ρ sits on
// the PSF's ρ★, a resolved galaxy's below it. Stellarity = L_star / (L_star + L_galaxy), equal
// priors: a bright star → 1, a bright galaxy → 0, an object lost in noise → ≈ 0.5.
// Derivation: docs/algorithms.md#stellarity
#pragma once

#include "shapesim/detect.hpp"
#include "shapesim/model.hpp"
#include "shapesim/resample.hpp"

namespace shapesim {

/// Where point sources sit in the core-fraction statistic.
struct PointSourceLocus {
    double fwhm = 0.0;     ///< PSF FWHM, image pixels
    double r_core = 0.0;   ///< core aperture radius, pixels
    double r_outer = 0.0;  ///< outer aperture radius, pixels
    double ratio = 0.0;    ///< ρ★: mean core fraction of the PSF over sub-pixel phases
    double scatter = 0.0;  ///< s★: phase scatter ⊕ 2 % model floor
};

/// The locus of a Gaussian PSF of `fwhm_pixels`.
PointSourceLocus gaussian_point_source_locus(double fwhm_pixels);
/// The locus of a shapelet PSF model in image pixels (its centre is ignored).
PointSourceLocus model_point_source_locus(const ShapeletModel& psf);
/// The locus of a PSF image sampled at `psf_pixel_scale` for an image at `image_pixel_scale`
/// (arcsec per pixel; the PSF must be at least as finely sampled). The PSF's centre is its
/// flux centroid. Error when the image is empty, non-finite or has no positive flux.
PointSourceLocus image_point_source_locus(const ImageArray& psf, double psf_pixel_scale,
                                          double image_pixel_scale);

// box_convolve (a PSF image convolved with a detector pixel or drizzle drop) lives in
// resample.hpp, included above, with the rest of the pixel-resampling maths.

/// Core fraction ρ of a detection and its error.
struct CoreFraction {
    double ratio = 0.0, error = 0.0;
};
CoreFraction core_fraction(const DetectionResult& field, const Detection& object,
                           const PointSourceLocus& locus);

/// Stellarity in [0, 1] from a measured core fraction (docs/algorithms.md#stellarity).
double stellarity(const CoreFraction& measured, const PointSourceLocus& locus);

}  // namespace shapesim
