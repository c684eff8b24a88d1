// One galaxy's morphology record (shapesim.morph/1, DESIGN §2, §5) from a detected field:
// SExtractor-style photometry and shape from detection (detect.hpp, sources.hpp), e1, e2
// (paper eqs. 6–7), and the statistics of morphometry.hpp on a statmorph-style cutout (the
// segment's box × 2.5, at least 48 pixels). A statistic that cannot be computed is left out;
// flags (small, faint, crowded, no_sky) say when one is unreliable.
// Fields, cutout and flags: docs/algorithms.md#morphology-records
#pragma once

#include "shapesim/detect.hpp"
#include "shapesim/morphometry.hpp"
#include "shapesim/psf_field.hpp"
#include "shapesim/records.hpp"
#include "shapesim/shear_estimate.hpp"

#include <memory>
#include <optional>

namespace shapesim {

struct MeasureOptions {
    MorphometryOptions morphometry;
    double cutout_extent = 2.5;
    int min_cutout = 48;
    double min_petrosian = 2.0;
    double min_snr = 10.0;
    double max_neighbour_fraction = 0.1;
    /// Circular aperture photometry (SExtractor's MAG_APER) of radius `aperture_radius`
    /// pixels about the detection's centroid, every pixel weighted by its area inside
    /// (exact_aperture.hpp): flux_aper and mag_aper (with `zero_point`). 0: none.
    double aperture_radius = 0.0;
    double zero_point = 0.0;  ///< AB magnitude of one image unit, for mag_aper
    /// Stars (kind "star"): a circular Moffat, I ∝ (1 + r²/α²)^−β integrated over each pixel
    /// (4 × 4-point Gauss–Legendre), fitted with a constant by least squares over a box of
    /// ±3 FWHM (the object's own and unlabelled good pixels): fwhm_moffat = 2α √(2^{1/β} − 1)
    /// (pixels) and beta_moffat: the seeing, free of the pixel's width FWHM_IMAGE carries.
    bool fit_star_profile = true;
    /// The PSF's adaptive moments (shear_estimate.hpp): each galaxy also gets its PSF-corrected
    /// shear estimate shear_e1, shear_e2 (responsivity 1), shear_resolution R and
    /// shear_sigma (√ of the adaptive moments' determinant^½, pixels), from adaptive moments
    /// on its cutout with other objects' and bad pixels left out; flag "shear_failed" (and
    /// the reason in shear_why) when there is none. Unset: none.
    std::optional<AdaptiveMoments> shear_psf;
    /// A PSF varying across the image (psf_field.hpp): when set, each galaxy's estimate is
    /// corrected by the PSF's adaptive moments at its own place, and shear_psf is unused.
    std::shared_ptr<const PsfField> shear_psf_field;
};

/// The Moffat fitted to a star (MeasureOptions::fit_star_profile).
struct MoffatFit {
    double x = 0.0, y = 0.0;  ///< centre, 0-based pixel coordinates of `image`
    double fwhm = 0.0, beta = 0.0, amplitude = 0.0, background = 0.0;
    bool converged = false;
};

/// The least-squares pixel-integrated circular Moffat (plus a constant) of the pixels of
/// `image` where `use` is non-zero, from the start (x, y, fwhm); 0-based coordinates.
MoffatFit fit_moffat(const ImageArray& image, const MaskArray& use, double x, double y,
                     double fwhm);

/// The record of `object` of `field`; `source` is its detection record (shapesim-detect's
/// fields: mag, stellarity, kind, flags). Throws Error when the statistics cannot start (no
/// positive flux in the segment).
MorphRecord measure_object(const DetectionResult& field, const Detection& object,
                           const SourceRecord& source, const MeasureOptions& options = {});

}  // namespace shapesim
