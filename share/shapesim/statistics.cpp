#include "shapesim/statistics.hpp"

#include "shapesim/error.hpp"
#include "shapesim/rng.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace shapesim {

double mean_of(const std::vector<double>& v) {
    if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
    double s = 0.0;
    for (double x : v) s += x;
    return s / double(v.size());
}

double rms_of(const std::vector<double>& v) {
    if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
    const double m = mean_of(v);
    double s = 0.0;
    for (double x : v) s += (x - m) * (x - m);
    return std::sqrt(s / double(v.size()));
}

double sorted_quantile(const std::vector<double>& sorted, double p) {
    if (sorted.empty()) return std::numeric_limits<double>::quiet_NaN();
    const double at = p * double(sorted.size()) - 0.5;
    const std::size_t lo = std::size_t(std::max(0.0, std::floor(at)));
    const std::size_t hi = std::min(lo + 1, sorted.size() - 1);
    const double t = std::clamp(at - double(lo), 0.0, 1.0);
    return sorted[lo] + t * (sorted[hi] - sorted[lo]);
}

double normal_cdf(double z) { return 0.5 * std::erfc(-z / std::sqrt(2.0)); }

double median_of_values(std::vector<double> v) {
    if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double bootstrap_error(const std::vector<double>& values,
                       const std::function<double(const std::vector<double>&)>& statistic,
                       int resamples, std::uint64_t seed) {
    if (values.size() < 2 || resamples < 2) return std::numeric_limits<double>::quiet_NaN();
    std::vector<double> stats, sample(values.size());
    for (int k = 0; k < resamples; ++k) {
        RandomStream r(seed, std::uint64_t(k), "bootstrap");
        for (double& x : sample) x = values[r.uniform_index(values.size())];
        stats.push_back(statistic(sample));
    }
    return rms_of(stats);
}

double kolmogorov_q(double lambda) {
    if (lambda < 1e-3) return 1.0;
    double sum = 0.0, sign = 1.0;
    for (int k = 1; k <= 100; ++k) {
        const double term = std::exp(-2.0 * k * k * lambda * lambda);
        sum += sign * term;
        if (term < 1e-12) break;
        sign = -sign;
    }
    return std::clamp(2.0 * sum, 0.0, 1.0);
}

KsResult ks_two_sample(std::vector<double> a, std::vector<double> b) {
    require(!a.empty() && !b.empty(), "a KS test needs two non-empty samples");
    std::sort(a.begin(), a.end());
    std::sort(b.begin(), b.end());
    const double na = double(a.size()), nb = double(b.size());
    std::size_t i = 0, j = 0;
    double d = 0.0;
    while (i < a.size() && j < b.size()) {
        const double x = std::min(a[i], b[j]);
        while (i < a.size() && a[i] <= x) ++i;
        while (j < b.size() && b[j] <= x) ++j;
        d = std::max(d, std::abs(double(i) / na - double(j) / nb));
    }
    const double ne = na * nb / (na + nb), root = std::sqrt(ne);
    return {d, kolmogorov_q((root + 0.12 + 0.11 / root) * d)};
}

double wasserstein_1d(std::vector<double> a, std::vector<double> b) {
    require(!a.empty() && !b.empty(), "a Wasserstein distance needs two non-empty samples");
    std::sort(a.begin(), a.end());
    std::sort(b.begin(), b.end());
    // ∫ |F_a − F_b| over the merged breakpoints.
    std::vector<double> x(a);
    x.insert(x.end(), b.begin(), b.end());
    std::sort(x.begin(), x.end());
    double w = 0.0;
    std::size_t i = 0, j = 0;
    for (std::size_t k = 0; k + 1 < x.size(); ++k) {
        while (i < a.size() && a[i] <= x[k]) ++i;
        while (j < b.size() && b[j] <= x[k]) ++j;
        w += std::abs(double(i) / double(a.size()) - double(j) / double(b.size())) *
             (x[k + 1] - x[k]);
    }
    return w;
}

double upper_median(std::vector<double>& values) {
    if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
    const auto middle = values.begin() + std::ptrdiff_t(values.size() / 2);
    std::nth_element(values.begin(), middle, values.end());
    return *middle;
}

}  // namespace shapesim
