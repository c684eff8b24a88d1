#include "shapesim/compare.hpp"

#include "shapesim/error.hpp"
#include "shapesim/rng.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

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
        w += std::abs(double(i) / double(a.size()) - double(j) / double(b.size())) * (x[k + 1] - x[k]);
    }
    return w;
}

std::vector<double> Catalogue::column(const std::string& field, double mag_limit) const {
    std::vector<double> out;
    for (const Json& r : records) {
        if (r.contains("kind") && r.at("kind") != "galaxy") continue;
        if (!r.contains("mag") || !r.at("mag").is_number() || r.at("mag").get<double>() > mag_limit)
            continue;
        auto number = [&](const char* key) -> std::optional<double> {
            if (!r.contains(key) || !r.at(key).is_number()) return std::nullopt;
            const double v = r.at(key).get<double>();
            return std::isfinite(v) ? std::optional<double>(v) : std::nullopt;
        };
        std::optional<double> v;
        if (field == "fwhm_arcsec") {
            const auto f = number("fwhm"), scale = number("pixel_scale");
            if (f && scale) v = *f * *scale;
        } else if (field == "e") {
            const auto e1 = number("e1"), e2 = number("e2");
            if (e1 && e2) v = std::hypot(*e1, *e2);
        } else {
            v = number(field.c_str());
        }
        if (v) out.push_back(*v);
    }
    return out;
}

TableRow table_row(const Catalogue& catalogue, const TableCuts& cuts) {
    TableRow t;
    t.name = catalogue.name;
    t.galaxies = long(catalogue.column("mag", cuts.mag_counts).size());
    auto both = [&](const std::vector<double>& v, double& mean, double& mean_err, double& rms,
                    double& rms_err, std::uint64_t salt) {
        mean = mean_of(v);
        rms = rms_of(v);
        mean_err = bootstrap_error(v, mean_of, cuts.resamples, cuts.seed + salt);
        rms_err = bootstrap_error(v, rms_of, cuts.resamples, cuts.seed + salt + 1);
    };
    both(catalogue.column("c", cuts.mag_ca), t.c_mean, t.c_mean_err, t.c_rms, t.c_rms_err, 0);
    both(catalogue.column("a_sym", cuts.mag_ca), t.a_mean, t.a_mean_err, t.a_rms, t.a_rms_err, 10);
    both(catalogue.column("s", cuts.mag_s), t.s_mean, t.s_mean_err, t.s_rms, t.s_rms_err, 20);
    // rms e: the rms of the ellipticity modulus about 0, as the paper's "rms e".
    const std::vector<double> e = catalogue.column("e", cuts.mag_counts);
    auto rms0 = [](const std::vector<double>& v) {
        double s = 0.0;
        for (double x : v) s += x * x;
        return v.empty() ? std::numeric_limits<double>::quiet_NaN() : std::sqrt(s / double(v.size()));
    };
    t.e_rms = rms0(e);
    t.e_rms_err = bootstrap_error(e, rms0, cuts.resamples, cuts.seed + 30);
    const std::vector<double> f = catalogue.column("fwhm_arcsec", cuts.mag_counts);
    t.fwhm_median = median_of_values(f);
    t.fwhm_median_err = bootstrap_error(f, median_of_values, cuts.resamples, cuts.seed + 40);
    t.fwhm_sd = rms_of(f);
    t.fwhm_sd_err = bootstrap_error(f, rms_of, cuts.resamples, cuts.seed + 41);
    return t;
}

TableRow table_row_from_json(const Json& row) {
    if (!row.is_object() || !row.contains("name") || !row.at("name").is_string())
        throw Error("missing or not a string", "", 0, "name");
    constexpr double nan = std::numeric_limits<double>::quiet_NaN();
    TableRow t;
    t.name = row.at("name").get<std::string>();
    t.galaxies = -1;
    for (double* v : {&t.c_mean, &t.c_mean_err, &t.c_rms, &t.c_rms_err, &t.a_mean, &t.a_mean_err,
                      &t.a_rms, &t.a_rms_err, &t.s_mean, &t.s_mean_err, &t.s_rms, &t.s_rms_err,
                      &t.e_rms, &t.e_rms_err, &t.fwhm_median, &t.fwhm_median_err, &t.fwhm_sd,
                      &t.fwhm_sd_err})
        *v = nan;
    const std::pair<const char*, double*> fields[] = {
        {"c_mean", &t.c_mean}, {"c_rms", &t.c_rms}, {"a_mean", &t.a_mean}, {"a_rms", &t.a_rms},
        {"s_mean", &t.s_mean}, {"s_rms", &t.s_rms}, {"e_rms", &t.e_rms},
        {"fwhm_median", &t.fwhm_median}, {"fwhm_sd", &t.fwhm_sd}};
    for (const auto& [name, value] : fields) {
        if (!row.contains(name)) continue;
        if (!row.at(name).is_number()) throw Error("not a number", "", 0, name);
        *value = row.at(name).get<double>();
    }
    if (row.contains("n")) {
        if (!row.at("n").is_number_integer()) throw Error("not a whole number", "", 0, "n");
        t.galaxies = row.at("n").get<long>();
    }
    return t;
}

}  // namespace shapesim
