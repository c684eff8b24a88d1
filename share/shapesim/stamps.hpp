// Postage stamps of detected objects, with the noise renormalised locally (paper §2.1).
//
// A stamp is square, centred on the pixel holding the centroid, with an odd side of at least
// size_factor·a + size_offset pixels (the method's 3·A_IMAGE + 5). That is enough for a faint
// galaxy but cuts a bright extended one well inside its own isophote (an HDF I = 20.7 spiral:
// 45 px against an isophotal area of 6233 px, 79 px across), so the side also covers the
// object's segment (bounding box, measured from the centre) plus `sky_margin` pixels of sky,
// and its Kron aperture (kron_factor·r_K·a). It is then grown ×1.25 while the border
// is not sky: the object's own segment reaches the border ring, or the ring's unowned pixels
// are significantly bright (mean z above `border_sigmas`·F/√n, F the field's correlated-noise
// factor): faint wings beyond the isophote. At most `max_side` pixels; clipped at the image
// edge.
// Planes: the background-subtracted image; the inverse-variance weight (0 at bad pixels);
// a mask, 1 where the pixel belongs to another object in the segmentation map.
//
// Noise renormalisation: drizzled weight maps misstate the pixel-to-pixel noise (HDF: ×≈2 in
// σ), and the absolute level matters to χ²_r in the shapelet fit. The stamp's border ring
// (`border_width` pixels deep) gives the pixels owned by no object and not touching one; their
// normalised values z = I·√w have unit rms when the weights are right. The weights are
// multiplied by 1/σ(z)² (clipped_sigma, detect.hpp), so the stamp's own noise fixes its χ²
// scale. A 3a + 5 stamp of a faint galaxy has only a few dozen such pixels (σ(z) to ±13% from
// 30), so while there are fewer than `min_border_pixels` the sky around the stamp is added,
// out to `max_margin` pixels beyond it; then pixels touching a segment are allowed; below
// that the field-wide factor is kept and the stamp flagged "noise_global".
//
// Source photon noise. With a gain g (electrons per image unit) a pixel of value S carries the
// extra variance S/g. The weight is 1/(σ_sky² + max(S̄, 0)/g), σ_sky after the renormalisation
// and S̄ the 3×3 mean about the pixel (so a pixel's own noise peak does not lower its weight
// much). A bright galaxy's core is dominated by it (HDF, g = 865 200 e⁻ per DN/s: 21× the sky
// variance at the peak of the I = 20.7 spiral): without it χ²_r stays far above 1 at every
// order. The gain is the one shapesim-render draws photon noise with, so a simulation's stamps
// get the same weights as the real image's.
#pragma once

#include "shapesim/detect.hpp"
#include "shapesim/fits_io.hpp"

namespace shapesim {

struct StampOptions {
    double size_factor = 3.0;   ///< stamp side ≥ size_factor · a + size_offset (pixels)
    double size_offset = 5.0;
    double kron_factor = 2.5;   ///< side ≥ 2 · kron_factor · r_K · a + 1 (the Kron aperture)
    int sky_margin = 4;         ///< side ≥ the segment's extent + this, pixels, each side
    double border_sigmas = 3.0; ///< grow while the border ring's mean z exceeds this · F/√n
    int max_side = 513;         ///< the side is never grown beyond this (pixels, odd)
    double gain = 0.0;          ///< e⁻ per image unit for the source photon noise (0: none)
    int border_width = 2;       ///< depth of the border ring for the noise, pixels
    int min_border_pixels = 200;  ///< sky pixels wanted (σ to ±5%)
    int max_margin = 32;          ///< how far beyond the stamp to look for them, pixels

    /// Throws Error unless sizes are positive.
    void validate() const;
};

/// A stamp with its noise bookkeeping.
struct CutStamp {
    Stamp stamp;                ///< id, planes and FITS origin (x0, y0)
    double weight_scale = 1.0;  ///< factor applied to the input weight map (global × local)
    double noise_rms = 0.0;     ///< pixel noise σ at the stamp's median weight, image units
    int border_pixels = 0;      ///< sky pixels the local factor came from
    bool clipped = false;       ///< the edge cuts the paper's 3a + 5 square about the centre
    bool noise_global = false;  ///< too few sky pixels: the field-wide factor was kept
    int grown = 0;              ///< times the side was grown ×1.25 to reach sky
    bool border_not_sky = false;///< still not sky at `max_side` (or the image's size)
};

/// Add the source's photon noise at `gain` e⁻ per image unit to a stamp's sky weights (see the
/// file comment; its pixels' own 3×3 means, masked and zero-weight pixels included as they are).
void add_source_noise(Stamp& stamp, double gain);

/// The paper's side in pixels, size_factor·a + size_offset rounded up to odd (≥ 3).
int stamp_side(const Detection& object, const StampOptions& options);

/// The starting side of an object's stamp before any growth: the largest of stamp_side(),
/// the segment's extent about the centre with `sky_margin` pixels of sky, and the Kron
/// aperture's diameter; odd, at most `max_side` (but never below stamp_side()).
int extent_side(const Detection& object, const StampOptions& options);

/// Cut `object`'s stamp from a detection result (`field.sigma` gives the weights before the
/// local factor; `field.weight_scale` is the global factor already in them).
CutStamp cut_stamp(const DetectionResult& field, const Detection& object, const std::string& id,
                   const StampOptions& options);

/// `object`'s stamp on another band of the same pixel grid (`band` from band_field()), in the
/// pixels of its detection stamp `box` (origin and size; a joint fit needs the same pixels in
/// every band), with the band's own local noise renormalisation and photon noise
/// (`options.gain`: the band's). Error when the box does not fit the band's image.
CutStamp cut_band_stamp(const DetectionResult& band, const Detection& object,
                        const std::string& id, const Stamp& box, const StampOptions& options);

}  // namespace shapesim
