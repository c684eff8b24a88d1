#include "shapesim/compare.hpp"

#include "shapesim/error.hpp"
#include "shapesim/rng.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <ostream>

namespace shapesim {

namespace {

// A record's finite number `key`, when it has one.
std::optional<double> finite_number(const Json& r, const char* key) {
    if (!r.contains(key) || !r.at(key).is_number()) return std::nullopt;
    const double v = r.at(key).get<double>();
    return std::isfinite(v) ? std::optional<double>(v) : std::nullopt;
}

}  // namespace

std::vector<double> Catalogue::column(const std::string& field, double mag_limit) const {
    std::vector<double> out;
    for (const Json& r : records) {
        if (r.contains("kind") && r.at("kind") != "galaxy") continue;
        if (!r.contains("mag") || !r.at("mag").is_number() || r.at("mag").get<double>() > mag_limit)
            continue;
        auto number = [&](const char* key) { return finite_number(r, key); };
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
        return v.empty() ? std::numeric_limits<double>::quiet_NaN()
                         : std::sqrt(s / double(v.size()));
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

namespace {

// A galaxy of a measured catalogue, with what the paired comparison reads.
struct PairedGalaxy {
    double x, y, scale, fwhm_arcsec, mag;
};

std::vector<PairedGalaxy> paired_galaxies(const Catalogue& catalogue, double mag_limit) {
    std::vector<PairedGalaxy> out;
    for (const Json& r : catalogue.records) {
        if (r.contains("kind") && r.at("kind") != "galaxy") continue;
        auto number = [&](const char* key) {
            return finite_number(r, key).value_or(std::numeric_limits<double>::quiet_NaN());
        };
        const PairedGalaxy g{number("x"), number("y"), number("pixel_scale"),
                             number("fwhm") * number("pixel_scale"), number("mag")};
        if (!(g.mag <= mag_limit) || !std::isfinite(g.x) || !std::isfinite(g.y) ||
            !(g.scale > 0.0) || !(g.fwhm_arcsec > 0.0))
            continue;
        out.push_back(g);
    }
    return out;
}

double log_mean(const std::vector<double>& v) {
    double s = 0.0;
    for (double x : v) s += std::log(x);
    return v.empty() ? std::numeric_limits<double>::quiet_NaN() : s / double(v.size());
}

}  // namespace

PairedComparison compare_paired(const Catalogue& real, const std::vector<Catalogue>& replays,
                                double radius_arcsec, const TableCuts& cuts) {
    if (replays.empty()) throw Error("no replays to pair the real galaxies with");
    PairedComparison p;
    p.real = real.name;
    p.replay_count = long(replays.size());
    p.radius_arcsec = radius_arcsec;
    std::vector<PairedGalaxy> galaxies = paired_galaxies(real, cuts.mag_counts);
    if (galaxies.empty())
        throw Error("no galaxy with a FWHM at " + std::string("mag <= ") +
                        std::to_string(cuts.mag_counts),
                    real.name);
    std::sort(galaxies.begin(), galaxies.end(),
              [](const PairedGalaxy& a, const PairedGalaxy& b) { return a.mag < b.mag; });
    std::vector<std::vector<PairedGalaxy>> measured;
    for (const Catalogue& c : replays) measured.push_back(paired_galaxies(c, cuts.mag_counts));

    // Each real galaxy's pairs: FWHM ratios and magnitude changes.
    const std::size_t n = galaxies.size();
    std::vector<std::vector<double>> ratios(n), dmags(n);
    for (std::size_t g = 0; g < n; ++g)
        for (const auto& replay : measured) {
            const PairedGalaxy* best = nullptr;
            double best_d2 = std::numeric_limits<double>::infinity();
            for (const PairedGalaxy& m : replay) {
                const double d2 = (m.x - galaxies[g].x) * (m.x - galaxies[g].x) +
                                  (m.y - galaxies[g].y) * (m.y - galaxies[g].y);
                if (d2 < best_d2) best_d2 = d2, best = &m;
            }
            if (best && std::sqrt(best_d2) * galaxies[g].scale <= radius_arcsec) {
                ratios[g].push_back(best->fwhm_arcsec / galaxies[g].fwhm_arcsec);
                dmags[g].push_back(best->mag - galaxies[g].mag);
            }
        }
    auto row = [&](std::size_t lo, std::size_t hi) {
        PairedRow r;
        r.mag_lo = galaxies[lo].mag;
        r.mag_hi = galaxies[hi - 1].mag;
        r.galaxies = long(hi - lo);
        std::vector<double> per_galaxy, all_ratios, all_dmags;
        for (std::size_t g = lo; g < hi; ++g) {
            r.found += long(ratios[g].size());
            if (ratios[g].empty()) continue;
            ++r.paired_galaxies;
            per_galaxy.push_back(log_mean(ratios[g]));
            all_ratios.insert(all_ratios.end(), ratios[g].begin(), ratios[g].end());
            all_dmags.insert(all_dmags.end(), dmags[g].begin(), dmags[g].end());
        }
        constexpr double nan = std::numeric_limits<double>::quiet_NaN();
        const double l = per_galaxy.empty() ? nan : mean_of(per_galaxy);
        r.ratio_geomean = std::exp(l);
        r.ratio_geomean_err =
            r.ratio_geomean * bootstrap_error(per_galaxy, mean_of, cuts.resamples, cuts.seed + 50);
        r.ratio_median = all_ratios.empty() ? nan : median_of_values(all_ratios);
        r.ratio_mean = all_ratios.empty() ? nan : mean_of(all_ratios);
        r.dmag_median = all_dmags.empty() ? nan : median_of_values(all_dmags);
        return r;
    };
    // Quarters by magnitude (fewer rows for fewer than 8 galaxies), then all.
    const std::size_t parts = n >= 8 ? 4 : 1;
    for (std::size_t q = 0; q < parts && parts > 1; ++q)
        p.rows.push_back(row(q * n / parts, (q + 1) * n / parts));
    p.rows.push_back(row(0, n));

    // Unpaired: the catalogues' own FWHM distributions.
    std::vector<double> real_fwhm, replay_fwhm;
    for (const PairedGalaxy& g : galaxies) real_fwhm.push_back(g.fwhm_arcsec);
    for (const auto& replay : measured)
        for (const PairedGalaxy& g : replay) replay_fwhm.push_back(g.fwhm_arcsec);
    auto geomean = [](const std::vector<double>& v) { return std::exp(log_mean(v)); };
    p.real_galaxies = long(real_fwhm.size());
    p.replay_galaxies = long(replay_fwhm.size());
    p.real_geomean = geomean(real_fwhm);
    p.real_geomean_err = bootstrap_error(real_fwhm, geomean, cuts.resamples, cuts.seed + 60);
    p.real_median = median_of_values(real_fwhm);
    p.real_median_err =
        bootstrap_error(real_fwhm, median_of_values, cuts.resamples, cuts.seed + 61);
    p.replay_geomean = geomean(replay_fwhm);
    p.replay_geomean_err = bootstrap_error(replay_fwhm, geomean, cuts.resamples, cuts.seed + 62);
    p.replay_median = median_of_values(replay_fwhm);
    p.replay_median_err =
        bootstrap_error(replay_fwhm, median_of_values, cuts.resamples, cuts.seed + 63);
    return p;
}

void write_paired_markdown(std::ostream& out, const PairedComparison& p, const std::string& band,
                           const TableCuts& cuts) {
    char buf[4096];  // a line with catalogue names up to ~3,800 characters
    std::snprintf(buf, sizeof buf,
                  "| %s | galaxies (%s) | found in %ld replays (within %g\") | FWHM ratio, "
                  "geometric mean | median | mean | Δ%s, median |\n|---|---|---|---|---|---|---|\n",
                  band.c_str(), p.real.c_str(), p.replay_count, p.radius_arcsec, band.c_str());
    out << buf;
    for (std::size_t k = 0; k < p.rows.size(); ++k) {
        const PairedRow& r = p.rows[k];
        const long pairs = r.galaxies * p.replay_count;
        char range[64];
        if (k + 1 == p.rows.size())
            std::snprintf(range, sizeof range, "all (%.2f–%.2f)", r.mag_lo, r.mag_hi);
        else
            std::snprintf(range, sizeof range, "%.2f–%.2f", r.mag_lo, r.mag_hi);
        std::snprintf(buf, sizeof buf,
                      "| %s | %ld | %ld/%ld (%.0f%%) | %.3f ± %.3f | %.3f | %.3f | %+.3f |\n",
                      range, r.galaxies, r.found, pairs, 100.0 * double(r.found) / double(pairs),
                      r.ratio_geomean, r.ratio_geomean_err, r.ratio_median, r.ratio_mean,
                      r.dmag_median);
        out << buf;
    }
    std::snprintf(buf, sizeof buf,
                  "\nGalaxies with %s ≤ %g, unpaired: FWHM geometric mean %.4f″ ± %.4f (%s, %ld) "
                  "and %.4f″ ± %.4f (the replays, %ld pooled: %+.1f%%); median %.4f″ ± %.4f "
                  "and %.4f″ ± %.4f (%+.1f%%). Errors: %d bootstrap resamples.\n",
                  band.c_str(), cuts.mag_counts, p.real_geomean, p.real_geomean_err,
                  p.real.c_str(), p.real_galaxies, p.replay_geomean, p.replay_geomean_err,
                  p.replay_galaxies,
                  100.0 * (p.replay_geomean / p.real_geomean - 1.0), p.real_median,
                  p.real_median_err, p.replay_median, p.replay_median_err,
                  100.0 * (p.replay_median / p.real_median - 1.0), cuts.resamples);
    out << buf;
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

namespace {

// A Table cell: "v ± err", "v" without an error, "–" without a value.
std::string table_cell(double v, double err, int digits = 3) {
    char buf[64];
    if (!std::isfinite(v)) return "–";
    if (std::isfinite(err))
        std::snprintf(buf, sizeof buf, "%.*f ± %.*f", digits, v, digits, err);
    else
        std::snprintf(buf, sizeof buf, "%.*f", digits, v);
    return buf;
}

}  // namespace

void write_table_markdown(std::ostream& o, const std::vector<TableRow>& rows,
                          const std::string& band, const TableCuts& cuts) {
    o << "| catalogue | N (" << band << " ≤ " << cuts.mag_counts
      << ") | ⟨C⟩ | rms C | ⟨A⟩ | rms A | ⟨S⟩ | rms S"
      << " | rms e | FWHM median (″) | FWHM sd (″) "
         "|\n|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const TableRow& t : rows) {
        o << "| " << t.name << " | " << (t.galaxies >= 0 ? std::to_string(t.galaxies) : "–")
          << " | " << table_cell(t.c_mean, t.c_mean_err) << " | "
          << table_cell(t.c_rms, t.c_rms_err) << " | " << table_cell(t.a_mean, t.a_mean_err)
          << " | " << table_cell(t.a_rms, t.a_rms_err) << " | "
          << table_cell(t.s_mean, t.s_mean_err) << " | " << table_cell(t.s_rms, t.s_rms_err)
          << " | " << table_cell(t.e_rms, t.e_rms_err) << " | "
          << table_cell(t.fwhm_median, t.fwhm_median_err) << " | "
          << table_cell(t.fwhm_sd, t.fwhm_sd_err) << " |\n";
    }
    o << "\nC and A for " << band << " ≤ " << cuts.mag_ca << ", S (×10, Conselice 2003) for "
      << band << " ≤ " << cuts.mag_s << ", e and FWHM for " << band << " ≤ " << cuts.mag_counts
      << "; errors: " << cuts.resamples << " bootstrap resamples.\n";
}

void write_distances_markdown(std::ostream& o, const std::vector<Catalogue>& catalogues,
                              const TableCuts& cuts) {
    o << "| statistic | catalogue | n | n (" << catalogues.at(0).name
      << ") | KS D | KS p | Wasserstein |\n|---|---|---|---|---|---|---|\n";
    const std::pair<const char*, double> stats[] = {
        {"mag", cuts.mag_counts}, {"fwhm_arcsec", cuts.mag_counts},
        {"e", cuts.mag_counts},   {"r_petro", cuts.mag_ca},
        {"c", cuts.mag_ca},       {"a_sym", cuts.mag_ca},
        {"s", cuts.mag_s},        {"gini", cuts.mag_ca},
        {"m20", cuts.mag_ca}};
    for (const auto& [field, limit] : stats) {
        const std::vector<double> ref = catalogues[0].column(field, limit);
        for (std::size_t k = 1; k < catalogues.size(); ++k) {
            const std::vector<double> v = catalogues[k].column(field, limit);
            o << "| " << field << " | " << catalogues[k].name << " | " << v.size() << " | "
              << ref.size() << " | ";
            if (v.empty() || ref.empty()) {
                o << "– | – | – |\n";
                continue;
            }
            const KsResult ks = ks_two_sample(ref, v);
            char buf[128];
            std::snprintf(buf, sizeof buf, "%.3f | %.3g | %.4g |\n", ks.d, ks.p_value,
                          wasserstein_1d(ref, v));
            o << buf;
        }
    }
}

void write_figure_data(std::ostream& o, const Catalogue& catalogue) {
    o << "# mag fwhm_arcsec e c a_sym s r_petro_arcsec\n";
    for (const Json& r : catalogue.records) {
        if (r.contains("kind") && r.at("kind") != "galaxy") continue;
        auto num = [&](const char* key) {
            return r.contains(key) && r.at(key).is_number()
                       ? r.at(key).get<double>()
                       : std::numeric_limits<double>::quiet_NaN();
        };
        const double scale = num("pixel_scale");
        const double values[] = {num("mag"),
                                 num("fwhm") * scale,
                                 std::hypot(num("e1"), num("e2")),
                                 num("c"),
                                 num("a_sym"),
                                 num("s"),
                                 num("r_petro") * scale};
        for (double v : values) {
            if (std::isfinite(v))
                o << v << ' ';
            else
                o << "NaN ";
        }
        o << '\n';
    }
}

void write_figures_script(std::ostream& o, const std::string& folder,
                          const std::vector<Catalogue>& catalogues, const std::string& band,
                          const TableCuts& cuts) {
    o << "# gnuplot " << folder << "/figures.gp (run from the parent folder)\n"
      << "set terminal pngcairo size 640,480 enhanced font 'DejaVu Sans,11'\nset key top left\n"
      << "set datafile missing 'NaN'\nbin(x, w) = w * floor(x / w) + w / 2.0\n";
    // One figure: its setup, then `each` once per catalogue with FILE and NAME filled in.
    auto plot = [&](const char* name, const std::string& setup, const std::string& each) {
        o << "set output '" << folder << "/" << name << ".png'\n" << setup << "\nplot ";
        for (std::size_t k = 0; k < catalogues.size(); ++k) {
            std::string line = each;
            const std::string file = "'" + folder + "/" + catalogues[k].name + ".dat'";
            for (std::size_t p; (p = line.find("FILE")) != std::string::npos;)
                line.replace(p, 4, file);
            for (std::size_t p; (p = line.find("NAME")) != std::string::npos;)
                line.replace(p, 4, catalogues[k].name);
            o << (k ? ", \\\n     " : "") << line;
        }
        o << "\nunset logscale\n";
    };
    const std::string mcut = std::to_string(cuts.mag_counts), ca = std::to_string(cuts.mag_ca),
                      scut = std::to_string(cuts.mag_s);
    plot("counts",
         "set title 'Number counts (Fig. 5)'\nset xlabel 'I'\nset ylabel 'N per 0.5 mag'\nset "
         "logscale y",
         "FILE using (bin($1,0.5)):(1.0) smooth frequency with histeps title 'NAME'");
    plot("size",
         "set title 'Size distribution, " + band + " <= " + mcut +
             " (Fig. 6)'\nset xlabel 'FWHM (arcsec)'\nset ylabel 'N'",
         "FILE using ($1 <= " + mcut +
             " ? bin($2,0.05) : NaN):(1.0) smooth frequency with histeps title 'NAME'");
    plot("size_mag",
         "set title 'Size against magnitude (Fig. 7)'\nset xlabel 'I'\nset ylabel 'FWHM "
         "(arcsec)'\nset logscale y",
         "FILE using 1:2 with points pt 7 ps 0.4 title 'NAME'");
    plot("ellipticity",
         "set title 'Ellipticity, " + band + " <= " + mcut +
             " (Fig. 8)'\nset xlabel '|e|'\nset ylabel 'N'",
         "FILE using ($1 <= " + mcut +
             " ? bin($3,0.05) : NaN):(1.0) smooth frequency with histeps title 'NAME'");
    plot("c_a",
         "set title 'Concentration against asymmetry, " + band + " <= " + ca +
             " (Fig. 9)'\nset xlabel 'A'\nset ylabel 'C'",
         "FILE using ($1 <= " + ca + " ? $5 : NaN):4 with points pt 7 ps 0.6 title 'NAME'");
    plot("c_rp",
         "set title 'Concentration against Petrosian radius, " + band + " <= " + ca +
             " (Fig. 10)'\nset xlabel 'r_p (arcsec)'\nset ylabel 'C'",
         "FILE using ($1 <= " + ca + " ? $7 : NaN):4 with points pt 7 ps 0.6 title 'NAME'");
    plot("a_s",
         "set title 'Asymmetry against clumpiness, " + band + " <= " + scut +
             " (Fig. 11)'\nset xlabel 'S'\nset ylabel 'A'",
         "FILE using ($1 <= " + scut + " ? $6 : NaN):5 with points pt 7 ps 0.6 title 'NAME'");
}

}  // namespace shapesim
