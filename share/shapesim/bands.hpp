// Multi-band fields (issue 17), detection side: SExtractor's dual-image mode. Objects are
// detected once, on a detection image (a stack of the bands, or one band); every band of the
// same pixel grid is then measured in the detection's apertures and cut into stamps of the
// detection's boxes, so that colours compare like with like and a joint fit sees the same
// pixels in every band.
//
// Each band keeps its own noise: bad pixels, background, the weight map rescaled to its
// measured rms (the XDF's weights misstate it ×≈15 in variance), the correlated-noise factor
// of its own sky, and its stamps' local renormalisation and photon noise (its own gain).
#pragma once

#include "shapesim/detect.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/records.hpp"
#include "shapesim/stamps.hpp"

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace shapesim {

/// One band measured on the detection's grid.
struct BandField {
    BandRecord spec;
    DetectionResult field;                ///< band_field(): its noise, the detection's segments
    std::vector<ApertureFlux> auto_flux;  ///< forced FLUX_AUTO of each detection object
    /// Forced flux in each object's inner circle (inner_radius()): with the AUTO flux, the
    /// inner and outer colours of a colour gradient.
    std::vector<ApertureFlux> inner_flux;
    DetectionOptions options;             ///< the detection's, with the band's gain
};

/// The inner aperture of a colour gradient: a circle of half the AUTO ellipse's geometric-mean
/// radius, r·√(ab) / 2 with r = max(kron_factor·r_K, kron_min_radius), but no wider than the
/// ellipse's minor semi-axis r·b, and at least 1.5 pixels (≈ the half-light radius; the outer
/// colour is that of the AUTO flux outside it).
double inner_radius(const Detection& object, const DetectionOptions& options);

/// Read every band's image and noise map (Error naming the file on a missing or mis-sized
/// one) and measure it on `detection`'s grid with the detection `options` (GAIN: the band's
/// when given, else none).
std::vector<BandField> measure_bands(const std::vector<BandRecord>& bands,
                                     const DetectionResult& detection,
                                     const DetectionOptions& options);

/// The `bands` entry of the source record of detection object `k` in `band`: band, flux
/// (forced FLUX_AUTO), flux_err, mag (with a zero point and a positive flux), flux_inner and
/// flux_inner_err (the inner circle), zero_point,
/// noise_correlation, background_rms, and, with a stamp (`cut`, written to `stamps_file`),
/// stamp_hdu, noise_rms, weight_scale, border_pixels.
Json band_source_entry(const BandField& band, std::size_t k, const CutStamp* cut,
                       const std::string& stamps_file);

/// Add detection object `k`'s (`object`'s) bands to its `record` (a `bands` list of
/// band_source_entry()), and, when the object has a detection stamp `cut`, its stamp in every
/// band (cut_band_stamp(), HDU band_stamp_hdu()) to `stamps` (`stamps_file` its name in the
/// records); `options` are the detection stamps' (each band's own gain replaces theirs).
void add_bands(SourceRecord& record, const std::vector<BandField>& bands, std::size_t k,
               const Detection& object, const CutStamp* cut, FitsWriter* stamps,
               const std::string& stamps_file, const StampOptions& options);

/// The HDU name of a band's stamp of object `id`: "<id>.<band>".
std::string band_stamp_hdu(const std::string& id, const std::string& band);

}  // namespace shapesim
