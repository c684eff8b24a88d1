// Catalogue comparison (compare.hpp): KS p-values uniform for one population and small for two,
// Wasserstein of a shift, bootstrap errors, the Kolmogorov tail.
#include "shapesim/compare.hpp"

#include "shapesim/error.hpp"
#include "shapesim/rng.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>
#include <sstream>

using namespace shapesim;

namespace {

std::vector<double> normal_sample(std::uint64_t seed, std::uint64_t id, int n, double shift) {
    RandomStream r(seed, id, "compare test");
    std::vector<double> v;
    for (int k = 0; k < n; ++k) v.push_back(shift + r.gaussian());
    return v;
}

}  // namespace

// The Kolmogorov tail at known points (Q(0.5) = 0.9639, Q(1) = 0.2700, Q(1.36) = 0.0494).
TEST(Compare, KolmogorovTail) {
    EXPECT_NEAR(kolmogorov_q(0.5), 0.963945, 1e-5);
    EXPECT_NEAR(kolmogorov_q(1.0), 0.269999, 1e-5);
    EXPECT_NEAR(kolmogorov_q(1.36), 0.049392, 1e-4);
    EXPECT_EQ(kolmogorov_q(0.0), 1.0);
}

// Two samples of one population, 400 times: p-values uniform (5% below 0.05 within binomial
// error, mean 0.5); a 0.5σ shift at n = 200 is rejected every time.
TEST(Compare, KsPValuesAreUniformForOnePopulationAndSmallForTwo) {
    int below = 0, rejected = 0;
    double mean_p = 0.0;
    const int repeats = 400;
    for (int k = 0; k < repeats; ++k) {
        const KsResult same = ks_two_sample(normal_sample(1, 2 * std::uint64_t(k), 200, 0.0),
                                            normal_sample(1, 2 * std::uint64_t(k) + 1, 150, 0.0));
        mean_p += same.p_value / repeats;
        if (same.p_value < 0.05) ++below;
        const KsResult other = ks_two_sample(normal_sample(2, std::uint64_t(k), 200, 0.0),
                                             normal_sample(3, std::uint64_t(k), 200, 0.5));
        if (other.p_value < 0.01) ++rejected;
    }
    std::cout << "  [measured] fraction p < 0.05 = " << double(below) / repeats
              << ", mean p = " << mean_p << ", rejected at 1% = " << double(rejected) / repeats << "\n";
    EXPECT_NEAR(double(below) / repeats, 0.05, 3.0 * std::sqrt(0.05 * 0.95 / repeats));
    EXPECT_NEAR(mean_p, 0.5, 0.05);
    EXPECT_GT(double(rejected) / repeats, 0.9);
    EXPECT_THROW(ks_two_sample({}, {1.0}), Error);
}

// Wasserstein: a sample and its copy shifted by δ are δ apart; identical samples 0.
TEST(Compare, WassersteinOfAShift) {
    const std::vector<double> a = normal_sample(4, 0, 300, 0.0);
    std::vector<double> b = a;
    for (double& x : b) x += 0.37;
    EXPECT_NEAR(wasserstein_1d(a, b), 0.37, 1e-12);
    EXPECT_NEAR(wasserstein_1d(a, a), 0.0, 1e-15);
    EXPECT_NEAR(wasserstein_1d({0.0}, {1.0, 3.0}), 2.0, 1e-15);
}

// The bootstrap error of a mean is σ/√n (to 10%), and reproducible.
TEST(Compare, BootstrapErrorOfTheMean) {
    const std::vector<double> v = normal_sample(5, 0, 400, 1.0);
    const double e = bootstrap_error(v, mean_of, 1000, 9);
    EXPECT_NEAR(e, rms_of(v) / std::sqrt(400.0), 0.1 * rms_of(v) / 20.0);
    EXPECT_EQ(e, bootstrap_error(v, mean_of, 1000, 9));
    EXPECT_NEAR(median_of_values({3.0, 1.0, 2.0, 10.0}), 2.5, 1e-15);
}

// A published row: the values given, NaN (and n = −1) for the rest; a wrong type is named.
TEST(Compare, PublishedTableRow) {
    const TableRow t = table_row_from_json(Json::parse(R"({"name":"paper","c_mean":3.11,"e_rms":0.64})"));
    EXPECT_EQ(t.name, "paper");
    EXPECT_EQ(t.c_mean, 3.11);
    EXPECT_EQ(t.e_rms, 0.64);
    EXPECT_EQ(t.galaxies, -1);
    EXPECT_TRUE(std::isnan(t.c_mean_err));
    EXPECT_TRUE(std::isnan(t.a_mean));
    EXPECT_EQ(table_row_from_json(Json::parse(R"({"name":"x","n":12})")).galaxies, 12);
    try {
        table_row_from_json(Json::parse(R"({"name":"x","c_rms":"0.4"})"));
        FAIL() << "accepted a string";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("c_rms"), std::string::npos) << e.what();
    }
    EXPECT_THROW(table_row_from_json(Json::parse(R"({"c_mean":1})")), Error);
}

// statistics.hpp: the upper median takes the ⌊n/2⌋-th smallest; median_of_values averages
// the two middle values of an even sample.
TEST(Statistics, UpperMedianAndMedian) {
    std::vector<double> even = {4.0, 1.0, 3.0, 2.0}, odd = {5.0, -1.0, 2.0}, none;
    EXPECT_EQ(median_of_values(even), 2.5);
    EXPECT_EQ(upper_median(even), 3.0);
    EXPECT_EQ(upper_median(odd), 2.0);
    EXPECT_TRUE(std::isnan(upper_median(none)));
    EXPECT_TRUE(std::isnan(median_of_values(none)));
}

// The report's writers: the Table with "–" for what is absent, the distances' rows, the
// figures' data (NaN where absent, galaxies only) and a script naming every catalogue's data.
TEST(CompareReport, WritersFormatTheirFiles) {
    Catalogue a{"hdf", {}}, b{"sim", {}};
    for (int k = 0; k < 5; ++k) {
        a.records.push_back(Json{{"mag", 22.0 + k},
                                 {"fwhm", 3.0},
                                 {"pixel_scale", 0.04},
                                 {"e1", 0.3},
                                 {"e2", 0.4},
                                 {"c", 3.0 + 0.1 * k}});
        b.records.push_back(
            Json{{"mag", 22.0 + 0.5 * k}, {"c", 2.5 + 0.1 * k}, {"kind", "galaxy"}});
    }
    b.records.push_back(Json{{"mag", 20.0}, {"kind", "star"}});
    TableCuts cuts;
    cuts.resamples = 10;
    TableRow paper;
    paper.name = "paper";
    paper.galaxies = -1;
    paper.c_mean = 2.9;
    paper.c_mean_err = std::numeric_limits<double>::quiet_NaN();
    paper.c_rms = std::numeric_limits<double>::quiet_NaN();
    std::ostringstream table;
    write_table_markdown(table, {paper}, "I", cuts);
    EXPECT_NE(table.str().find("| paper | – | 2.900 | – |"), std::string::npos) << table.str();
    EXPECT_NE(table.str().find("| catalogue | N (I ≤ 29) |"), std::string::npos);
    EXPECT_NE(table.str().find("errors: 10 bootstrap resamples.\n"), std::string::npos);

    std::ostringstream distances;
    write_distances_markdown(distances, {a, b}, cuts);
    EXPECT_NE(distances.str().find("| n (hdf) |"), std::string::npos);
    EXPECT_NE(distances.str().find("| c | sim | 5 | 5 | 1.000 |"), std::string::npos)
        << distances.str();
    EXPECT_NE(distances.str().find("| fwhm_arcsec | sim | 0 | 5 | – | – | – |"), std::string::npos);

    std::ostringstream data;
    write_figure_data(data, b);
    const std::string text = data.str();
    EXPECT_EQ(text.substr(text.find('\n') + 1, 28), "22 NaN NaN 2.5 NaN NaN NaN \n");
    EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 6);

    std::ostringstream script;
    write_figures_script(script, "out", {a, b}, "I", cuts);
    EXPECT_NE(script.str().find("set output 'out/a_s.png'"), std::string::npos);
    EXPECT_NE(script.str().find("'out/sim.dat' using 1:2 with points pt 7 ps 0.4 title 'sim'"),
              std::string::npos);
}

// Paired catalogues: real galaxies on a grid; replays with every FWHM × 1.1 (one galaxy found
// in one replay only, one never, one shifted past the radius), a star and a galaxy fainter than
// the cut left out. The geometric-mean ratio is 1.1 exactly, the finds are counted per quarter
// and the unpaired geometric means are the catalogues' own.
TEST(Compare, PairedRatiosAreTheReplaysOverTheRealGalaxies) {
    auto record = [](double x, double y, double fwhm, double mag) {
        return Json{{"x", x}, {"y", y}, {"fwhm", fwhm}, {"pixel_scale", 0.05}, {"mag", mag},
                    {"kind", "galaxy"}};
    };
    Catalogue real{"real", {}};
    for (int k = 0; k < 16; ++k)
        real.records.push_back(record(10.0 + 20 * k, 50.0, 4.0 + k % 3, 22.0 + 0.25 * k));
    real.records.push_back(record(500, 500, 3, 20.0));
    real.records.back()["kind"] = "star";
    real.records.push_back(record(600, 600, 3, 30.0));  // fainter than the cut
    std::vector<Catalogue> replays(2);
    for (int r = 0; r < 2; ++r) {
        replays[size_t(r)].name = "r" + std::to_string(r);
        for (int k = 0; k < 16; ++k) {
            if (k == 15 || (k == 14 && r == 1)) continue;  // 15 never found, 14 once
            const double dx = k == 13 ? 3.0 : 0.5;         // 13: 0.15″ away, past 0.1″
            replays[size_t(r)].records.push_back(
                record(10.0 + 20 * k + dx, 50.0, 1.1 * (4.0 + k % 3), 22.1 + 0.25 * k));
        }
    }
    TableCuts cuts;
    cuts.resamples = 200;
    const PairedComparison p = compare_paired(real, replays, 0.1, cuts);
    ASSERT_EQ(p.rows.size(), 5u);  // four quarters and all
    const PairedRow& all = p.rows.back();
    EXPECT_EQ(all.galaxies, 16);
    EXPECT_EQ(all.found, 2 * 13 + 1);
    EXPECT_EQ(all.paired_galaxies, 14);
    EXPECT_NEAR(all.ratio_geomean, 1.1, 1e-12);
    EXPECT_NEAR(all.ratio_median, 1.1, 1e-12);
    EXPECT_NEAR(all.ratio_mean, 1.1, 1e-12);
    EXPECT_NEAR(all.ratio_geomean_err, 0.0, 1e-12);
    EXPECT_NEAR(all.dmag_median, 0.1, 1e-12);
    EXPECT_EQ(p.rows[0].found, 8);  // the brightest four, in both replays
    EXPECT_EQ(p.rows[3].found, 2 + 0 + 1 + 0);  // 12, 13 (too far), 14 (once), 15
    EXPECT_DOUBLE_EQ(p.rows[3].mag_lo, 25.0);
    EXPECT_DOUBLE_EQ(p.rows[3].mag_hi, 25.75);
    double log_real = 0.0;
    for (int k = 0; k < 16; ++k) log_real += std::log(0.05 * (4.0 + k % 3));
    EXPECT_NEAR(p.real_geomean, std::exp(log_real / 16), 1e-12);
    EXPECT_EQ(p.real_galaxies, 16);
    EXPECT_EQ(p.replay_galaxies, 15 + 14);

    std::ostringstream md;
    write_paired_markdown(md, p, "I", cuts);
    EXPECT_NE(md.str().find("| all (22.00–25.75) | 16 | 27/32 (84%) | 1.100 ± 0.000 | 1.100 | "
                            "1.100 | +0.100 |"),
              std::string::npos)
        << md.str();
    EXPECT_THROW(compare_paired(real, {}, 0.1, cuts), Error);
}
