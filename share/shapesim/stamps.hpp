// Postage stamps of detected objects, with the noise renormalised locally (paper §2.1).
// A stamp is square and odd-sided, at least size_factor·a + size_offset pixels (the method's
// 3·A_IMAGE + 5), widened to the object's segment, Kron aperture and sky around them. Planes:
// the background-subtracted image; the inverse-variance weight (0 at bad pixels); a mask,
// 1 on other objects' pixels. The weights are rescaled so the border's sky has unit rms and
// carry the source's photon noise: w = 1/(σ_sky² + max(S̄, 0)/g).
// Derivation: docs/algorithms.md#postage-stamps
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

/// Add the source's photon noise at `gain` e⁻ per image unit to a stamp's sky weights
/// (docs/algorithms.md#postage-stamps; its pixels' own 3×3 means, masked and zero-weight pixels
/// included as they are).
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
