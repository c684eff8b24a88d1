// Sample statistics shared by the comparisons (compare.hpp, colours.hpp, noise.hpp) and the
// detection: mean, rms, medians, bootstrap errors, two-sample distances.
//
//  - bootstrap_error: the standard deviation of a statistic over `resamples` resamplings
//    with replacement, drawn from RandomStream(seed, resample, "bootstrap") — reproducible.
//  - ks_two_sample: the Kolmogorov–Smirnov statistic D = sup |F_a − F_b| and its asymptotic
//    p-value Q_KS((√n_e + 0.12 + 0.11/√n_e) D), n_e = n_a n_b/(n_a + n_b) (Stephens 1970).
//  - wasserstein_1d: ∫ |F_a − F_b| dx, the earth mover's distance in the statistic's units.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

namespace shapesim {

double mean_of(const std::vector<double>& v);
/// Population standard deviation (the paper's "rms").
double rms_of(const std::vector<double>& v);
double median_of_values(std::vector<double> v);
/// The quantile at probability p of the ascending values `sorted`: value i stands at
/// (i + ½)/n, linear between, the end values beyond. NaN when empty.
double sorted_quantile(const std::vector<double>& sorted, double p);
/// The standard normal CDF Φ(z).
double normal_cdf(double z);

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
/// The upper median (the ⌊n/2⌋-th smallest, 0-based) in O(n): reorders `values`. NaN when
/// empty. (SExtractor's weight-map rescaling takes it; median_of_values averages the two
/// middle values.)
double upper_median(std::vector<double>& values);

}  // namespace shapesim
