// colours.hpp: colours and gradients from dual-image source records, and their comparison.
#include "shapesim/colours.hpp"

#include "shapesim/error.hpp"
#include "shapesim/rng.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <sstream>

using namespace shapesim;

namespace {

// A source record with bands g, r (AUTO and inner-circle fluxes) at detection magnitude `mag`.
SourceRecord source(const std::string& id, double mag, double g, double r, double g_in,
                    double r_in) {
    SourceRecord s;
    s.id = id;
    s.mag = mag;
    s.flux = 1.0;
    Json bands = Json::array();
    bands.push_back({{"band", "g"}, {"flux", g}, {"flux_err", 0.01}, {"flux_inner", g_in}});
    bands.push_back({{"band", "r"}, {"flux", r}, {"flux_err", 0.01}, {"flux_inner", r_in}});
    s.extra["bands"] = bands;
    return s;
}

// `n` galaxies of colour g − r normal about `mean` (σ 0.2), magnitudes 22–28.
ColourCatalogue sample(const std::string& name, int n, double mean, std::uint64_t seed) {
    std::vector<SourceRecord> records;
    RandomStream stream(seed, 0, "colours");
    for (int k = 0; k < n; ++k) {
        const double colour = mean + 0.2 * stream.gaussian();
        const double r = 1.0, g = std::pow(10.0, -0.4 * colour);
        records.push_back(source(std::to_string(k), 22.0 + 6.0 * stream.uniform(), g, r, 0.4 * g, 0.5 * r));
    }
    return ColourCatalogue::from_records(name, records);
}

}  // namespace

TEST(Colours, ColourAndGradientOfOneGalaxy) {
    // Inner: g 1, r 2 (colour 0.753); outer: g 2, r 2 (colour 0): a red core.
    const ColourCatalogue c = ColourCatalogue::from_records(
        "one", {source("1", 24.0, 3.0, 4.0, 1.0, 2.0), source("2", 29.0, 1.0, 1.0, 0.5, 0.5)});
    ASSERT_EQ(c.galaxies.size(), 2u);
    const std::vector<double> colours = c.colours(0, 28.0);
    ASSERT_EQ(colours.size(), 1u);  // the second is fainter than the limit
    EXPECT_NEAR(colours[0], -2.5 * std::log10(3.0 / 4.0), 1e-12);
    const std::vector<double> gradients = c.gradients(0, 28.0);
    ASSERT_EQ(gradients.size(), 1u);
    EXPECT_NEAR(gradients[0], 2.5 * std::log10(2.0), 1e-12);
    // A non-positive flux has no colour; a record without bands is an error.
    EXPECT_TRUE(ColourCatalogue::from_records("x", {source("1", 24.0, -1.0, 4.0, 1.0, 2.0)})
                    .colours(0, 28.0)
                    .empty());
    SourceRecord bare;
    bare.id = "7";
    EXPECT_THROW(ColourCatalogue::from_records("x", {bare}), Error);
}

// Two draws of one population agree; a population 0.3 mag redder is told apart, in the mean
// (in σ) and by KS; the report names every catalogue and colour.
TEST(Colours, ComparisonTellsAShiftedPopulationApart) {
    const std::vector<ColourCatalogue> catalogues = {sample("real", 300, 0.5, 1), sample("same", 300, 0.5, 2),
                                                     sample("redder", 300, 0.8, 3)};
    const auto k = compare_colours(catalogues, 28.0, 200, 5);
    ASSERT_EQ(k.size(), 3u);
    ASSERT_EQ(k[0].size(), 1u);
    EXPECT_EQ(k[0][0].colour, "g-r");
    EXPECT_EQ(k[0][0].colour_ks.d, 0.0);
    EXPECT_GT(k[1][0].colour_ks.p_value, 0.01);
    EXPECT_LT(std::abs(k[1][0].mean_offset_sigmas), 3.5);
    EXPECT_NEAR(k[1][0].mean_error, 0.2 / std::sqrt(300.0), 0.004);
    EXPECT_LT(k[2][0].colour_ks.p_value, 1e-6);
    EXPECT_GT(k[2][0].mean_offset_sigmas, 10.0);
    std::ostringstream report;
    write_colour_report(report, catalogues, k, 28.0);
    for (const char* text : {"| g-r | real |", "| g-r | redder |", "Colour-magnitude"})
        EXPECT_NE(report.str().find(text), std::string::npos) << text;
    ColourCatalogue other = catalogues[1];
    other.bands = {"g", "i"};
    EXPECT_THROW(compare_colours({catalogues[0], other}, 28.0, 10, 1), Error);
}
