// From detections to `shapesim.source/1` records: the catalogue shapesim-detect writes.
//
// A record carries what downstream stages need without the big image (paper §2.1, DESIGN §2):
// position (FITS pixels and, with a WCS, RA/Dec), Kron flux and magnitude, shape, FWHM,
// stellarity, flags; its stamp (`stamp_file`, `stamp_hdu` = the id, origin `stamp_x0/y0`,
// size), the local noise (`noise_rms`, `weight_scale`), the field's (`background_rms`, and its
// correlated-noise factor `noise_correlation`), `pixel_scale`, `zero_point` and the
// source `image`. Extra measurements keep their SExtractor meaning: `flux_iso`, `iso_area`,
// `npix`, `peak`, `x_peak`/`y_peak`, `kron_radius`, `sigma`, `threshold`, plus
// `core_fraction` (the stellarity statistic, stellarity.hpp) and `kind` ("star"/"galaxy").
#pragma once

#include "shapesim/detect.hpp"
#include "shapesim/geometry.hpp"
#include "shapesim/records.hpp"
#include "shapesim/stamps.hpp"
#include "shapesim/stellarity.hpp"

#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace shapesim {

class FitsReader;
class FitsWriter;
struct BandField;

/// Facts about the field every record of one run shares.
struct SourceContext {
    std::string image;           ///< source image, as the user named it
    double pixel_scale = 0.0;    ///< arcsec per pixel
    double zero_point = 0.0;     ///< mag = zero_point − 2.5 log₁₀ flux
    std::optional<Wcs> wcs;      ///< for ra, dec
    std::string stamps;          ///< stamps file (empty: no stamps written)
    double star_threshold = 0.97;///< stellarity above which `kind` is "star"
    double noise_correlation = 1.0;  ///< DetectionResult::noise_correlation of the field
    double background_rms = 0.0;     ///< DetectionResult::background_rms of the field
};

/// The record of one detection; `cut` is its stamp (null when no stamps are written).
SourceRecord source_record(const Detection& object, const CoreFraction& core,
                           double stellarity_value, const CutStamp* cut,
                           const SourceContext& context);

/// What catalogue_sources() left out or set aside.
struct CatalogueTally {
    long stars = 0;                ///< stellarity above context.star_threshold, or saturated
    long saturated = 0;            ///< of them, saturated (Detection flag "saturated")
    long single_pixel_events = 0;  ///< cosmic rays, hot pixels: not recorded at all
};

/// One recorded detection, as catalogue_sources() hands it on.
using SourceSink = std::function<void(const Detection& object, const SourceRecord& record,
                                      bool is_star, double stellarity_value)>;

/// The catalogue of a detected field, in label order: every object but the single-pixel
/// events (is_single_pixel_event: no PSF, so no stellarity) gets its stellarity against
/// `locus`, a stamp in `stamps` (when given; a star's only with `stamp_stars`, since nobody
/// reads it otherwise), its `bands` (measure_bands(), in the same boxes) and a record to
/// `sink`. `stamp` are the stamps' options; `context.stamps` names the file in the records.
/// With `only`, just those objects (indices into field.objects, in that order): a tile's own.
CatalogueTally catalogue_sources(const DetectionResult& field, const PointSourceLocus& locus,
                                 const SourceContext& context,
                                 const std::vector<BandField>& bands, const StampOptions& stamp,
                                 FitsWriter* stamps, bool stamp_stars, const SourceSink& sink,
                                 const std::vector<std::size_t>* only = nullptr);

/// A field's background noise as shapesim-detect measured it.
struct FieldNoise {
    double rms = 0.0;          ///< image units
    double correlation = 1.0;  ///< correlated-noise factor F (≥ 1)
};

/// The field's noise from the records at `path`: their background_rms (the median of the
/// stamps' noise_rms when no record has one), and the median noise_correlation (1 when none
/// has one). Error (file and line) on a bad record, or when no record has either rms.
FieldNoise read_field_noise(const std::string& path);

/// A photometric zero point (AB magnitude of one image unit) from the header: MAGZPT,
/// MAGZERO, ZEROPNT, ZP or PHOTZP as given; else HST's PHOTFLAM/PHOTPLAM as AB,
/// ZP = −2.5 log₁₀ PHOTFLAM − 5 log₁₀ PHOTPLAM − 2.408. nullopt when none is there.
std::optional<double> header_zero_point(FitsReader& fits);

}  // namespace shapesim
