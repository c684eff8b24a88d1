// Comparing measured catalogues (shapesim-measure --compare; paper §5, its Table and
// Figs. 5–11): summary statistics with bootstrap errors, two-sample distances.
//
//  - bootstrap_error: the standard deviation of a statistic over `resamples` resamplings
//    with replacement, drawn from RandomStream(seed, resample, "bootstrap") — reproducible.
//  - ks_two_sample: the Kolmogorov–Smirnov statistic D = sup |F_a − F_b| and its asymptotic
//    p-value Q_KS((√n_e + 0.12 + 0.11/√n_e) D), n_e = n_a n_b/(n_a + n_b) (Stephens 1970).
//  - wasserstein_1d: ∫ |F_a − F_b| dx, the earth mover's distance in the statistic's units.
#pragma once

#include "shapesim/jsonl.hpp"

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace shapesim {

double mean_of(const std::vector<double>& v);
/// Population standard deviation (the paper's "rms").
double rms_of(const std::vector<double>& v);
double median_of_values(std::vector<double> v);

/// Standard deviation of `statistic` over bootstrap resamples of `values`.
double bootstrap_error(const std::vector<double>& values,
                       const std::function<double(const std::vector<double>&)>& statistic,
                       int resamples, std::uint64_t seed);

struct KsResult {
    double d = 0.0;        ///< sup |F_a − F_b|
    double p_value = 1.0;  ///< asymptotic probability of a D this large from one population
};
/// Throws Error when either sample is empty.
KsResult ks_two_sample(std::vector<double> a, std::vector<double> b);
/// The Kolmogorov distribution's tail Q(λ) = 2 Σ_{k≥1} (−1)^{k−1} e^{−2k²λ²}.
double kolmogorov_q(double lambda);

/// ∫ |F_a − F_b| dx; throws Error when either sample is empty.
double wasserstein_1d(std::vector<double> a, std::vector<double> b);

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

}  // namespace shapesim
