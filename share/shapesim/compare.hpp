// Comparing measured catalogues (shapesim-measure --compare; paper §5, its Table and
// Figs. 5–11): the Table's summary statistics with bootstrap errors and the two-sample
// distances of every statistic (the statistics themselves: statistics.hpp), and the writers of
// the report's files.
#pragma once

#include "shapesim/jsonl.hpp"
#include "shapesim/statistics.hpp"

#include <cstdint>
#include <functional>
#include <ostream>
#include <string>
#include <vector>

namespace shapesim {

/// A statistic's column of a measured catalogue: the values of records that have `field`,
/// are galaxies (kind absent or "galaxy") and have mag ≤ `mag_limit`.
struct Catalogue {
    std::string name;
    std::vector<Json> records;  ///< shapesim.morph/1 records
    /// Values of `field` ("fwhm_arcsec" and "e" are derived: fwhm × pixel_scale, √(e1² + e2²)).
    std::vector<double> column(const std::string& field, double mag_limit) const;
};

/// One row of the paper's Table for a catalogue: mean and rms of C and A (mag ≤ `mag_ca`), of S
/// (mag ≤ `mag_s`), rms e, median and sd of the FWHM in arcsec (mag ≤ `mag_counts`), each with
/// its bootstrap error; counts.
struct TableRow {
    std::string name;
    long galaxies = 0;
    double c_mean = 0, c_mean_err = 0, c_rms = 0, c_rms_err = 0;
    double a_mean = 0, a_mean_err = 0, a_rms = 0, a_rms_err = 0;
    double s_mean = 0, s_mean_err = 0, s_rms = 0, s_rms_err = 0;
    double e_rms = 0, e_rms_err = 0;
    double fwhm_median = 0, fwhm_median_err = 0, fwhm_sd = 0, fwhm_sd_err = 0;
};
struct TableCuts {
    double mag_counts = 29.0, mag_ca = 26.0, mag_s = 25.0;
    int resamples = 1000;
    std::uint64_t seed = 0;
};
TableRow table_row(const Catalogue& catalogue, const TableCuts& cuts);

/// A published row to print alongside (the paper's own numbers): a JSON object with "name"
/// and any of the TableRow value names ("n", "c_mean", "c_rms", …, "fwhm_sd"); what is absent,
/// and every error, is NaN (n: −1). Throws Error naming the field on a wrong type.
TableRow table_row_from_json(const Json& row);

/// Real galaxies paired with their models drawn where they were (shapesim-sample --replay,
/// rendered with new noise and measured alike): each galaxy of `real` (mag ≤ cuts.mag_counts)
/// and the nearest galaxy of each replay within `radius_arcsec` (positions in the catalogues'
/// pixels: the replays are of the real image's field). Per quarter of the real galaxies by
/// magnitude and for all: how many were found, and the FWHM ratio replay/real as a geometric
/// mean over galaxies (each galaxy's mean log ratio over its replays; bootstrap error over
/// galaxies), the median and mean over pairs; the median magnitude change. Beside it, unpaired,
/// the geometric mean and median FWHM of the real catalogue and of the replays pooled.
struct PairedRow {
    double mag_lo = 0, mag_hi = 0;  ///< the real galaxies' magnitudes in this row
    long galaxies = 0, found = 0;   ///< real galaxies; of them × replays, pairs found
    long paired_galaxies = 0;       ///< real galaxies found in at least one replay
    double ratio_geomean = 0, ratio_geomean_err = 0, ratio_median = 0, ratio_mean = 0;
    double dmag_median = 0;
};
struct PairedComparison {
    std::string real;  ///< the real catalogue's name
    long replay_count = 0;
    double radius_arcsec = 0;
    std::vector<PairedRow> rows;  ///< the quarters, then all
    long real_galaxies = 0, replay_galaxies = 0;
    double real_geomean = 0, real_geomean_err = 0, replay_geomean = 0, replay_geomean_err = 0;
    double real_median = 0, real_median_err = 0, replay_median = 0, replay_median_err = 0;
};
/// Throws Error when `real` has no galaxy with a FWHM under the cut or there are no replays.
PairedComparison compare_paired(const Catalogue& real, const std::vector<Catalogue>& replays,
                                double radius_arcsec, const TableCuts& cuts);
/// The markdown table of a paired comparison (`band` names the magnitudes).
void write_paired_markdown(std::ostream& out, const PairedComparison& paired,
                           const std::string& band, const TableCuts& cuts);

// The --compare report, one writer per file of its folder (the caller owns the files: written
// atomically, they land whole or not at all).

/// table.md: the Table's header, one line per row (galaxies < 0 and NaN values print "–"), and
/// the cuts; `band` names the magnitudes ("I").
void write_table_markdown(std::ostream& out, const std::vector<TableRow>& rows,
                          const std::string& band, const TableCuts& cuts);
/// distances.md: per statistic (mag, fwhm_arcsec, e under mag_counts; r_petro, c, a_sym, gini,
/// m20 under mag_ca; s under mag_s), the KS statistic, its p-value and the 1D Wasserstein
/// distance of every catalogue from the first.
void write_distances_markdown(std::ostream& out, const std::vector<Catalogue>& catalogues,
                              const TableCuts& cuts);
/// NAME.dat, the figures' data: per galaxy "mag fwhm_arcsec e c a_sym s r_petro_arcsec" (NaN
/// where absent).
void write_figure_data(std::ostream& out, const Catalogue& catalogue);
/// figures.gp: the gnuplot script of Figs. 5–11, one PNG each into `folder`, from the
/// catalogues' `folder`/NAME.dat (paths as given: run from the folder's parent). `band` is
/// written into quoted titles: the caller keeps it a plain name.
void write_figures_script(std::ostream& out, const std::string& folder,
                          const std::vector<Catalogue>& catalogues, const std::string& band,
                          const TableCuts& cuts);

}  // namespace shapesim
