// Stellarity: the probability that a detection is a point source, from how concentrated it
// is compared with the PSF (libsep has no CLASS_STAR; this replaces it, documented and
// tested).
//
// Statistic: the core fraction ρ = F(r_core)/F(r_outer), fluxes in circular apertures about
// the centroid with r_core = 0.6·FWHM_psf and r_outer = 2·FWHM_psf (neighbours mirrored
// out). In a space image a star is the PSF, so its ρ sits on the PSF's value ρ★ (up to
// the sub-pixel phase, which moves flux between pixels), while any resolved galaxy is
// broader and has ρ < ρ★. Aperture fractions are used rather than the peak pixel because
// the peak of a faint object is biased up by noise (the brightest of several noisy pixels).
//
// Likelihoods, with σ_ρ the measurement error (propagated from the two aperture errors,
// the annulus independent of the core) and s★ the PSF's phase scatter plus a floor of
// 2% of ρ★ for PSF-model error:
//   star:    ρ ~ N(ρ★, s★² + σ_ρ²)
//   galaxy:  ρ = u + noise, u uniform on [0, ρ_g], ρ_g = ρ★ − 2 s★ (a galaxy is resolved: its
//            core fraction lies clearly below the PSF's; an unresolved one is a point
//            source to any classifier):  L = [Φ((ρ_g−ρ)/σ_ρ) − Φ(−ρ/σ_ρ)] / ρ_g
// Stellarity = L_star / (L_star + L_galaxy), equal priors. A bright star → 1, a bright
// resolved galaxy → 0, and an object whose ρ is lost in noise → ≈ 0.5, as CLASS_STAR does.
//
// The PSF may be given three ways, all reduced to pixelised stamps at the image's pixel scale
// at several sub-pixel phases: a Gaussian of given FWHM (SExtractor's SEEING_FWHM), a
// shapelet model (rendered exactly, pixel-integrated), or an image at its own (finer) pixel
// scale, integrated over each image pixel.
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

/// Stellarity in [0, 1] from a measured core fraction (formula in the file comment).
double stellarity(const CoreFraction& measured, const PointSourceLocus& locus);

}  // namespace shapesim
