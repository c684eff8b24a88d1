// One source's decomposition as shapesim-decompose runs it (paper §2.2): on the reading thread
// a DecomposeJob gathers the source record, its stamp, its bands' stamps, its PSF at the
// record's pixel scale and its noise correlation (JobReader, which keeps the open stamp files
// and the PSFs dilated once per pixel scale); on a worker decompose_job() fits it (one band:
// decompose() and shapelet_record(); several: decompose_joint()) and flags "bright_star";
// write_fit_images() writes its data, model and residual.
#pragma once

#include "shapesim/decompose.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/joint_bands.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/model.hpp"
#include "shapesim/noise.hpp"
#include "shapesim/psf_field.hpp"
#include "shapesim/records.hpp"

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace shapesim {

/// Where a source's β search starts: the detection's semi-major axis a in pixels (1 when the
/// record has none), at least 0.5 pixel.
double beta_start(const SourceRecord& source);

/// One source's fit inputs, read before any fit (cfitsio handles stay on one thread).
struct DecomposeJob {
    SourceRecord source;
    Stamp stamp;
    double pixel_scale = 0.0;              ///< arcsec per pixel, from the record
    std::optional<double> zero_point;      ///< absent or null: no magnitudes
    double noise_correlation = 1.0;        ///< F of the detection stamp's fit
    /// F forced for every band of a joint fit (--noise-correlation, --white-noise's 1);
    /// none: each band's own.
    std::optional<double> forced_noise_correlation;
    long line = 0;                         ///< the record's line in its file
    std::optional<CartesianModel> psf;     ///< the PSF at this record's pixel scale
    JointStamps joint;                     ///< several bands: the reference band first
};

/// A job's result: the record and its decomposition, or why the stamp could not be fitted.
struct DecomposeOutcome {
    std::optional<ShapeletRecord> record;
    std::optional<Decomposition> decomposition;
    std::string error;  ///< non-empty: the stamp could not be fitted at all
};

/// How JobReader turns a record into a job.
struct JobSettings {
    std::string stamps;          ///< every record's stamps file (empty: its stamp_file)
    std::string reference_band;  ///< the band whose model is the record's (empty: the first)
    bool bands = true;           ///< false: only the detection stamp, even with bands
    /// F for every fit instead of the record's noise_correlation (--noise-correlation).
    std::optional<double> noise_correlation;
    bool white_noise = false;    ///< F = 1 unless noise_correlation is given
};

/// Reads each record's job: its stamp and bands' stamps (files opened once), its typed
/// fields (errors placed at the reader's file and line) and its PSFs, dilated from arcsec to
/// the record's pixel scale once per scale (flux kept).
class JobReader {
public:
    /// Opens settings.stamps now: a missing file is an error even with nothing to fit.
    explicit JobReader(JobSettings settings);
    /// The PSF of every band without its own (a unit-flux model in arcsec, pixel scale 1).
    void set_psf(const ShapeletModel& psf_arcsec);
    /// A PSF varying across the image (in its pixels), taken at each source's x, y: the PSF
    /// of every band without its own, instead of set_psf's.
    void set_psf_field(std::shared_ptr<const PsfField> field);
    /// Band `band`'s own PSF (in arcsec).
    void add_band_psf(const std::string& band, const ShapeletModel& psf_arcsec);
    /// Band `band`'s measured sky-noise correlation (its exact noise take-up).
    void add_band_correlation(const std::string& band, const NoiseCorrelation& correlation);
    /// The job of `source`, the record `reader` has just read.
    DecomposeJob read(const SourceRecord& source, const JsonlReader& reader);

private:
    std::optional<CartesianModel> psf_at(const std::string& band, double pixel_scale);

    JobSettings settings_;
    StampFiles stamp_files_;
    std::optional<ShapeletModel> psf_arcsec_;
    std::shared_ptr<const PsfField> psf_field_;
    std::map<double, CartesianModel> psfs_;                             // by pixel scale
    std::map<std::string, ShapeletModel> band_psfs_;                    // arcsec
    std::map<std::pair<std::string, double>, CartesianModel> band_psfs_at_;  // by pixel scale
    std::map<std::string, NoiseCorrelation> band_correlations_;
};

/// Fit a job with `options` (its noise correlation and PSF set from the job's) and flag the
/// record "bright_star" when its model reaches a brighter star's wings (near_bright_star).
/// Never throws: an unfittable stamp's or an internal error's message is the outcome's error.
DecomposeOutcome decompose_job(const DecomposeJob& job, const DecomposeOptions& options,
                               const std::vector<SourceRecord>& stars);

/// `<id>.data`, `<id>.model`, `<id>.residual` (BITPIX −32, LTV1/2 placing them in the parent
/// image) of a job's fit: a joint fit's model is the reference band's, its data beside it.
void write_fit_images(FitsWriter& out, const DecomposeJob& job, const ShapeletFit& fit);

}  // namespace shapesim
