// Shear calibration (share/shapesim/calibration.hpp) on synthetic catalogues with known m and c,
// the matcher against brute force, and the catalogue reader (table.hpp read_numeric_columns)
// on the same numbers in every format it reads.
#include "shapesim/calibration.hpp"

#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/table.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <random>

using namespace shapesim;
using shapesim::test::TempDir;

namespace {

std::vector<ShearPoint> synthetic(long n, double m1, double c1, double m2, double c2, double noise,
                                  unsigned seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> g(-0.05, 0.05);
    std::normal_distribution<double> e(0.0, noise);
    std::vector<ShearPoint> points;
    for (long k = 0; k < n; ++k) {
        ShearPoint p;
        p.g1 = g(rng);
        p.g2 = g(rng);
        p.e1 = (1 + m1) * p.g1 + c1 + (noise > 0 ? e(rng) : 0.0);
        p.e2 = (1 + m2) * p.g2 + c2 + (noise > 0 ? e(rng) : 0.0);
        p.block = std::uint64_t(k);
        points.push_back(p);
    }
    return points;
}

}  // namespace

TEST(Calibration, RecoversInjectedBiasesExactlyWithoutNoise) {
    const ShearCalibration c = fit_shear_calibration(synthetic(500, 0.013, -4e-4, -0.021, 7e-4, 0.0, 1), 50, 3);
    EXPECT_NEAR(c.one.m, 0.013, 1e-12);
    EXPECT_NEAR(c.one.c, -4e-4, 1e-14);
    EXPECT_NEAR(c.two.m, -0.021, 1e-12);
    EXPECT_NEAR(c.two.c, 7e-4, 1e-14);
    EXPECT_LT(c.one.m_err, 1e-12);  // every resample gives the same line
    EXPECT_EQ(c.galaxies, 500);
    EXPECT_EQ(c.blocks, 500);
}

TEST(Calibration, NoisyRecoveryIsWithinItsBootstrapErrors) {
    // σ_e = 0.3 shape noise over 20000 galaxies with g uniform in ±0.05 (σ_g = 0.0289):
    // σ_m = σ_e / (σ_g √N) = 0.073, σ_c = σ_e/√N = 0.0021.
    const ShearCalibration c = fit_shear_calibration(synthetic(20000, 0.05, 1e-3, -0.05, -1e-3, 0.3, 7), 200, 5);
    EXPECT_NEAR(c.one.m_err, 0.073, 0.015);
    EXPECT_NEAR(c.one.c_err, 0.0021, 0.0004);
    EXPECT_NEAR(c.one.m, 0.05, 3 * c.one.m_err);
    EXPECT_NEAR(c.two.m, -0.05, 3 * c.two.m_err);
    EXPECT_NEAR(c.one.c, 1e-3, 3 * c.one.c_err);
    EXPECT_NEAR(c.two.c, -1e-3, 3 * c.two.c_err);
    // The same seed, the same errors.
    const ShearCalibration again =
        fit_shear_calibration(synthetic(20000, 0.05, 1e-3, -0.05, -1e-3, 0.3, 7), 200, 5);
    EXPECT_EQ(c.one.m_err, again.one.m_err);
}

TEST(Calibration, BlocksAreResampledWhole) {
    // Pairs whose noise cancels exactly: resampling whole pairs keeps the cancellation (the
    // error stays ~0); a galaxy-by-galaxy bootstrap would not.
    std::vector<ShearPoint> points = synthetic(400, 0.0, 0.0, 0.0, 0.0, 0.0, 2);
    for (std::size_t k = 0; k < points.size(); k += 2) {
        points[k + 1].g1 = points[k].g1;
        points[k + 1].g2 = points[k].g2;
        points[k].e1 += 0.3, points[k + 1].e1 = points[k + 1].g1 - 0.3;
        points[k].e2 = points[k].g2 - 0.2, points[k + 1].e2 = points[k + 1].g2 + 0.2;
        points[k + 1].e1 = points[k].g1 - 0.3;
        points[k].block = points[k + 1].block = k;
    }
    const ShearCalibration c = fit_shear_calibration(points, 100, 1);
    EXPECT_EQ(c.blocks, 200);
    EXPECT_NEAR(c.one.m, 0.0, 1e-10);
    EXPECT_LT(c.one.m_err, 1e-10);
    for (std::size_t k = 0; k < points.size(); ++k) points[k].block = k;
    EXPECT_GT(fit_shear_calibration(points, 100, 1).one.m_err, 0.2);  // ~0.3/(0.029·√400)
}

TEST(Calibration, OneShearHasNoSlope) {
    std::vector<ShearPoint> points = synthetic(100, 0, 0, 0, 0, 0.3, 4);
    for (ShearPoint& p : points) p.g1 = 0.02;
    try {
        fit_shear_calibration(points, 10, 1);
        FAIL() << "one shear fitted";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("g1 takes one value"), std::string::npos) << e.what();
    }
    EXPECT_THROW(fit_shear_calibration(synthetic(2, 0, 0, 0, 0, 0, 1), 10, 1), Error);
}

TEST(Calibration, BinsSplitByValue) {
    std::vector<ShearPoint> points = synthetic(1000, 0.0, 0.0, 0.0, 0.0, 0.0, 9);
    std::vector<double> mag(points.size());
    for (std::size_t k = 0; k < points.size(); ++k) {
        mag[k] = 20.0 + double(k % 10);
        // The faint half measures 10% low.
        if (mag[k] >= 25.0) points[k].e1 *= 0.9, points[k].e2 *= 0.9;
    }
    mag[3] = std::nan("");
    const std::vector<CalibrationBin> bins = fit_in_bins(points, mag, 2, 0, 1);
    ASSERT_EQ(bins.size(), 2u);
    EXPECT_EQ(bins[0].galaxies + bins[1].galaxies, 999);
    EXPECT_EQ(bins[0].hi, 24.0);
    EXPECT_EQ(bins[1].lo, 25.0);
    EXPECT_NEAR(bins[0].fit->one.m, 0.0, 1e-12);
    EXPECT_NEAR(bins[1].fit->two.m, -0.1, 1e-12);
}

TEST(Calibration, MatchingIsTheNearestWithinTheRadiusOncePerGalaxy) {
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> u(0.0, 500.0), d(-1.5, 1.5);
    std::vector<double> tx, ty, mx, my;
    for (int k = 0; k < 2000; ++k) tx.push_back(u(rng)), ty.push_back(u(rng));
    for (int k = 0; k < 2500; ++k) {
        const std::size_t t = std::size_t(k) % tx.size();
        mx.push_back(tx[t] + d(rng));
        my.push_back(ty[t] + d(rng));
    }
    const double radius = 1.0;
    const std::vector<long> match = match_nearest(tx, ty, mx, my, radius);
    // Brute force: the nearest within the radius, then one per galaxy, the nearer keeping it.
    std::vector<long> brute(mx.size(), -1);
    std::vector<double> dist(mx.size(), 1e300);
    for (std::size_t k = 0; k < mx.size(); ++k)
        for (std::size_t t = 0; t < tx.size(); ++t) {
            const double d2 = (tx[t] - mx[k]) * (tx[t] - mx[k]) + (ty[t] - my[k]) * (ty[t] - my[k]);
            if (d2 <= radius * radius && d2 < dist[k]) dist[k] = d2, brute[k] = long(t);
        }
    for (std::size_t k = 0; k < mx.size(); ++k)
        for (std::size_t q = 0; q < mx.size(); ++q)
            if (q != k && brute[k] >= 0 && brute[q] == brute[k] && dist[q] < dist[k]) {
                brute[k] = -2;  // lost to a nearer one
                break;
            }
    long matched = 0;
    for (std::size_t k = 0; k < mx.size(); ++k) {
        EXPECT_EQ(match[k], brute[k] == -2 ? -1 : brute[k]) << k;
        matched += match[k] >= 0;
    }
    EXPECT_GT(matched, 500);
    EXPECT_THROW(match_nearest(tx, ty, mx, my, 0.0), Error);
}

TEST(Calibration, CataloguesReadAlikeInEveryFormat) {
    TempDir dir;
    const std::string jsonl = dir.path() + "/c.jsonl", csv = dir.path() + "/c.csv",
                      sex = dir.path() + "/c.cat", fits = dir.path() + "/c.fits";
    std::ofstream(jsonl) << "{\"x\": 1.5, \"y\": 2, \"e1\": 0.1, \"e2\": -0.2, \"snr\": 30}\n"
                            "{\"x\": 3, \"y\": 4.25, \"e1\": null, \"e2\": 0.05}\n";
    std::ofstream(csv) << "x,y,e1,e2,snr\n1.5,2,0.1,-0.2,30\n3,4.25,,0.05,\n";
    std::ofstream(sex) << "#   1 NUMBER   Running object number\n"
                          "#   2 x        position [pixel]\n#   3 y\n#   4 e1\n#   5 e2\n#   6 snr\n"
                          "  1  1.5  2     0.1  -0.2   30\n  2  3    4.25  nan   0.05  nan\n";
    {
        CatalogueTable t;
        t.rows = 2;
        auto column = [](const char* name, std::vector<double> v) {
            CatalogueColumn c;
            c.name = name;
            c.type = CatalogueColumn::Type::real;
            c.numbers = std::move(v);
            return c;
        };
        const double nan = std::nan("");
        t.columns = {column("x", {1.5, 3}), column("y", {2, 4.25}), column("e1", {0.1, nan}),
                     column("e2", {-0.2, 0.05}), column("snr", {30, nan})};
        FitsWriter w(fits, "calibration_test");
        write_fits_table(w, t, "SHAPES");
        w.commit();
    }
    for (const std::string& path : {jsonl, csv, sex, fits}) {
        SCOPED_TRACE(path);
        const auto c = read_numeric_columns(path, {"x", "y", "e1", "e2"}, {"snr", "absent"});
        ASSERT_EQ(c.at("x").size(), 2u);
        EXPECT_EQ(c.at("x")[0], 1.5);
        EXPECT_EQ(c.at("y")[1], 4.25);
        EXPECT_EQ(c.at("e2")[0], -0.2);
        EXPECT_TRUE(std::isnan(c.at("e1")[1]));
        EXPECT_EQ(c.at("snr")[0], 30.0);
        EXPECT_TRUE(std::isnan(c.at("snr")[1]));
        EXPECT_EQ(c.count("absent"), 0u);
        EXPECT_THROW(read_numeric_columns(path, {"x", "e3"}), Error);
    }
}
