// Postage stamps of detected objects, with the noise renormalised locally (paper §2.1).
//
// A stamp is (size_factor·a + size_offset) pixels square (the method's 3·A_IMAGE + 5, rounded
// up to an odd number so the object's peak pixel is central), clipped at the image edge.
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
#pragma once

#include "shapesim/detect.hpp"
#include "shapesim/fits_io.hpp"

namespace shapesim {

struct StampOptions {
    double size_factor = 3.0;   ///< stamp side = size_factor · a + size_offset (pixels)
    double size_offset = 5.0;
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
    bool clipped = false;       ///< the stamp was cut short by the image edge
    bool noise_global = false;  ///< too few sky pixels: the field-wide factor was kept
};

/// The side in pixels of an object's stamp (odd, ≥ 3).
int stamp_side(const Detection& object, const StampOptions& options);

/// Cut `object`'s stamp from a detection result (`field.sigma` gives the weights before the
/// local factor; `field.weight_scale` is the global factor already in them).
CutStamp cut_stamp(const DetectionResult& field, const Detection& object, const std::string& id,
                   const StampOptions& options);

}  // namespace shapesim
