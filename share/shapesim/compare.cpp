#include "shapesim/compare.hpp"

#include "shapesim/error.hpp"
#include "shapesim/rng.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

namespace shapesim {

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
