// Multi-band fields (issue 17), decomposition side: a source's bands, cut by shapesim-detect
// --bands in the detection's box, read back with each band's PSF and noise and fitted jointly
// (decompose.hpp decompose_bands): one shape, each band's own flux and colour gradient.
#pragma once

#include "shapesim/decompose.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/model.hpp"
#include "shapesim/records.hpp"

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace shapesim {

/// One band of a source record (the `bands` list shapesim-detect --bands writes), as
/// shapesim-decompose reads it.
struct SourceBand {
    std::string band;
    std::string stamp_file, stamp_hdu;  ///< empty when no stamp was cut
    std::optional<double> zero_point;
    double noise_correlation = 1.0;
    double noise_rms = 0.0;             ///< the stamp's pixel σ (0: unknown)
};
/// The record's bands (empty when it has none); Error naming the field (e.g.
/// "bands[2].stamp_hdu") on a malformed entry or a repeated band.
std::vector<SourceBand> source_bands(const SourceRecord& record);

/// A source's joint-fit inputs: its bands (the reference band first), their stamps (all in the
/// detection stamp's box) and each band's PSF (field pixels, unit flux; none: fitted as seen).
struct JointStamps {
    std::vector<SourceBand> bands;
    std::vector<Stamp> stamps;
    std::vector<std::optional<CartesianModel>> psfs;
    /// Each band's measured noise correlation, in the bands' order (empty, or an entry
    /// without one: decompose's p·F² rule, or DecomposeOptions::correlation).
    std::vector<std::optional<NoiseCorrelation>> correlations;
};

/// Stamp files opened once, by name.
using StampFiles = std::map<std::string, std::unique_ptr<FitsReader>>;

/// Read the stamps of `bands` in their order (a file's stamps follow one another): each from
/// `stamps_file` when given, else its own stamp_file, else `record_file`; each must lie in
/// `box`; band b's PSF is psf_of(name). Then `reference` (when not empty) is put first. Error
/// (field "bands") on a band without a stamp, a stamp outside the box, or no such band.
JointStamps read_joint_stamps(
    std::vector<SourceBand> bands, const Stamp& box, const std::string& record_file,
    const std::string& stamps_file, const std::string& reference, StampFiles& files,
    const std::function<std::optional<CartesianModel>(const std::string&)>& psf_of);

/// The joint fit of a source's bands from (x, y) (stamp FITS coordinates) and scale
/// `beta_start` (decompose_bands(): each band's noise correlation, or `noise_correlation` for
/// all when given; 1/noise_rms its stack weight) and its record (shapelet_record() with the
/// bands' names and zero points, the reference band's PSF and zero point).
std::pair<Decomposition, ShapeletRecord> decompose_joint(
    const SourceRecord& source, const JointStamps& joint, const Stamp& box, double x, double y,
    double beta_start, const DecomposeOptions& options, double pixel_scale,
    std::optional<double> noise_correlation);

}  // namespace shapesim
