// Filling a field (sample.hpp): tiles, determinism, counts, star magnitudes.
#include "shapesim/sample.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/error.hpp"
#include "shapesim/moments.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <map>
#include <sstream>
#include <tuple>

using namespace shapesim;

namespace {

// A morphology of 30 random galaxy-like models, n_max 0–10, at 0.04″/pixel, zero point 25.
Morphology test_morphology() {
    std::vector<ShapeletRecord> records;
    for (int i = 0; i < 30; ++i) {
        ShapeletModel m = test::random_model(i % 11, 1.0 + 0.15 * i, 0.0, 0.0, 500 + i, true, 0.2);
        m.coeffs[0] = 1.0 + 0.3 * i;
        if (flux(m) <= 0.0) continue;
        ShapeletRecord r = ShapeletRecord::from_model(m, 0.04, "p" + std::to_string(i));
        r.mag = 22.0 + 0.2 * i;
        r.extra["zero_point"] = 25.0;
        records.push_back(r);
    }
    return build_morphology(records, SmoothOptions{});
}

FieldGeometry test_field(int nx, int ny) {
    FieldGeometry f;
    f.nx = nx;
    f.ny = ny;
    f.pixel_scale = 0.04;
    f.wcs = tan_wcs(150.0, 2.0, 0.04, 0.5 + nx / 2.0, 0.5 + ny / 2.0);
    return f;
}

// 3000 galaxies and 200 stars per arcmin², zero point 25, a 3-pixel margin.
SampleOptions crowded_options(std::uint64_t seed) {
    SampleOptions o;
    o.seed = seed;
    o.zero_point = 25.0;
    o.density = 3000.0;
    o.stars.density = 200.0;
    o.margin = 3.0;
    return o;
}

std::map<std::string, std::string> draw(const Morphology& m, const FieldGeometry& f,
                                        const SampleOptions& o, const std::optional<Tile>& tile) {
    std::map<std::string, std::string> out;
    sample_field(m, f, o, tile, [&](const ObjectRecord& r) { out[r.id] = r.to_json().dump(); });
    return out;
}

}  // namespace

// A 3×3 tiling: every tile's records are records of the whole field, bit for bit; their union
// is the whole field; an object sits in a tile only if its reach meets it; two runs agree.
TEST(Sample, TilesUnionIsTheWholeFieldRecordForRecord) {
    const Morphology m = test_morphology();
    const FieldGeometry f = test_field(600, 450);
    const SampleOptions o = crowded_options(11);
    const auto whole = draw(m, f, o, std::nullopt);
    ASSERT_GT(whole.size(), 100u);
    EXPECT_EQ(draw(m, f, o, std::nullopt), whole);
    std::map<std::string, std::string> merged;
    std::size_t emitted = 0;
    for (int j = 0; j < 3; ++j)
        for (int i = 0; i < 3; ++i) {
            const Tile t{1 + 200 * i, 1 + 150 * j, 200 * (i + 1), 150 * (j + 1)};
            const auto part = draw(m, f, o, t);
            emitted += part.size();
            for (const auto& [id, text] : part) {
                ASSERT_TRUE(whole.count(id)) << id;
                EXPECT_EQ(text, whole.at(id)) << id;
                const Json r = Json::parse(text);
                EXPECT_TRUE(t.reaches(r["x"], r["y"], r["reach"])) << id;
                merged[id] = text;
            }
        }
    EXPECT_EQ(merged, whole);
    EXPECT_GT(emitted, whole.size());  // objects near the tile edges are in more than one
}

// Sky cells of 128 pixels on a 600 × 450 field (5 × 4 cells, the last column and row narrower):
// a 3×3 tiling gives the whole field record for record; a small tile reads only the cells
// within the widest reach of it; every object lies in its cell; each cell's count is Poisson
// about density × its own area (the total's χ² over the 20 cells) and an exact count is shared
// out in proportion to area; a field of one cell draws what the default cell does.
TEST(Sample, SkyCellsKeyTheDraws) {
    const Morphology m = test_morphology();
    const FieldGeometry f = test_field(600, 450);
    SampleOptions o = crowded_options(12);
    o.cell = 128;
    const auto whole = draw(m, f, o, std::nullopt);
    std::map<std::string, std::string> merged;
    for (const Tile& t : tile_grid(600, 450, 200, 150))
        for (const auto& [id, text] : draw(m, f, o, t)) {
            ASSERT_TRUE(whole.count(id)) << id;
            EXPECT_EQ(text, whole.at(id)) << id;
            merged[id] = text;
        }
    EXPECT_EQ(merged, whole);
    // Objects in their cells, counts per cell.
    std::map<std::string, long> per_cell;
    for (const auto& [id, text] : whole) {
        const Json r = Json::parse(text);
        const double x = r["x"], y = r["y"];
        const long cell = long((y - 0.5) / 128) * 5 + long((x - 0.5) / 128);
        const auto dot = id.find('.');
        const long named = dot == std::string::npos ? 0 : std::stol(id.substr(1, dot - 1));
        EXPECT_EQ(cell, named) << id;
        if (id[0] == 'g') ++per_cell[std::to_string(cell)];
    }
    double chi2 = 0.0;
    for (long c = 0; c < 20; ++c) {
        const double w = c % 5 == 4 ? 600 - 512 : 128, h = c / 5 == 3 ? 450 - 384 : 128;
        const double expect = 3000.0 * w * h * 0.04 * 0.04 / 3600.0;
        const double d = double(per_cell[std::to_string(c)]) - expect;
        chi2 += d * d / expect;
    }
    EXPECT_LT(chi2, 45.3);  // χ²₂₀ at p = 0.001
    const SampleSummary small = sample_field(m, f, o, Tile{300, 200, 310, 210}, [](const ObjectRecord&) {});
    EXPECT_EQ(small.cells, 20u);
    EXPECT_LE(small.cells_read, 9u);
    EXPECT_GE(small.cells_read, 1u);
    o.count = 1001;
    o.star_count = 7;
    const SampleSummary exact = sample_field(m, f, o, std::nullopt, [](const ObjectRecord&) {});
    EXPECT_EQ(exact.galaxies, 1001u);
    EXPECT_EQ(exact.stars, 7u);
    // One cell: the same draw whatever the cell's size beyond the field.
    SampleOptions one = o, wider = o;
    one.cell = 600;
    wider.cell = 4096;
    EXPECT_EQ(draw(m, f, one, std::nullopt), draw(m, f, wider, std::nullopt));
    o.cell = 0;
    EXPECT_THROW(sample_field(m, f, o, std::nullopt, [](const ObjectRecord&) {}), Error);
}

// Counts: Poisson about density × area by default, exact with `count`; no galaxy fainter than
// the limit, and each record's flux matches its magnitude and its coefficients.
TEST(Sample, CountsMagnitudesAndFluxes) {
    const Morphology m = test_morphology();
    const FieldGeometry f = test_field(1500, 1500);  // 1 arcmin²
    SampleOptions o;
    o.seed = 3;
    o.zero_point = 25.0;
    o.mag_limit = 26.0;
    std::vector<ObjectRecord> galaxies;
    const SampleSummary s = sample_field(m, f, o, std::nullopt, [&](const ObjectRecord& r) {
        galaxies.push_back(r);
    });
    EXPECT_NEAR(double(s.galaxies), 700.0 * f.area_arcmin2(), 4.0 * std::sqrt(700.0));
    EXPECT_EQ(s.galaxies_out, s.galaxies);
    EXPECT_EQ(s.stars, 0u);
    for (const ObjectRecord& r : galaxies) {
        ASSERT_TRUE(r.mag.has_value());
        EXPECT_LE(*r.mag, 26.0);
        EXPECT_NEAR(r.flux, std::pow(10.0, -0.4 * (*r.mag - 25.0)), 1e-12 * r.flux);
        EXPECT_NEAR(flux(r.to_model(0.0, 0.0)), r.flux, 1e-10 * r.flux) << r.id;
        EXPECT_GE(*r.x, 0.5);
        EXPECT_LE(*r.x, 1500.5);
        const SkyPosition sky = f.wcs.pixel_to_sky(*r.x, *r.y);
        EXPECT_EQ(sky.ra, r.ra);
    }
    o.count = 17;
    EXPECT_EQ(sample_field(m, f, o, std::nullopt, [](const ObjectRecord&) {}).galaxies, 17u);
    o.mag_limit = 10.0;  // no parent that bright
    EXPECT_THROW(sample_field(m, f, o, std::nullopt, [](const ObjectRecord&) {}), Error);
}

// Star magnitudes follow the power-law counts (KS against N(<m) ∝ 10^{α(m−m0)} − 1) and a
// histogram's bins in proportion.
TEST(Sample, StarMagnitudesFollowTheCounts) {
    StarCounts c;
    c.slope = 0.3;
    c.mag_min = 18.0;
    c.mag_max = 28.0;
    std::vector<double> mags;
    RandomStream r(5, 0, "test");
    for (int i = 0; i < 20000; ++i) mags.push_back(c.magnitude(r.uniform()));
    std::sort(mags.begin(), mags.end());
    double d = 0.0;
    const double norm = std::pow(10.0, 0.3 * 10.0) - 1.0;
    for (std::size_t i = 0; i < mags.size(); ++i) {
        const double cdf = (std::pow(10.0, 0.3 * (mags[i] - 18.0)) - 1.0) / norm;
        d = std::max({d, std::abs(cdf - double(i) / 20000.0), std::abs(double(i + 1) / 20000.0 - cdf)});
    }
    EXPECT_LT(d, 0.0096);
    c.bins = {{20.0, 21.0, 1.0}, {21.0, 23.0, 3.0}};
    int low = 0;
    for (int i = 0; i < 8000; ++i) {
        const double m = c.magnitude(r.uniform());
        ASSERT_GE(m, 20.0);
        ASSERT_LE(m, 23.0);
        if (m < 21.0) ++low;
    }
    EXPECT_NEAR(low / 8000.0, 0.25, 0.02);
}

TEST(Sample, TileReachIsTheDistanceToThePixelArea) {
    const Tile t{11, 21, 20, 30};  // pixel area [10.5, 20.5] × [20.5, 30.5]
    EXPECT_TRUE(t.reaches(15.0, 25.0, 0.0));
    EXPECT_TRUE(t.reaches(8.5, 25.0, 2.0));
    EXPECT_FALSE(t.reaches(8.5, 25.0, 1.99));
    EXPECT_TRUE(t.reaches(23.5, 34.5, 5.0));   // corner: distance 5
    EXPECT_FALSE(t.reaches(23.5, 34.5, 4.99));
}

// The grid covers the field exactly once, and every point belongs to exactly one tile (the
// rule the truth catalogues of tiles are cut by).
TEST(Sample, TileGridPartitionsTheField) {
    const std::vector<Tile> grid = tile_grid(602, 452, 320, 240);
    ASSERT_EQ(grid.size(), 4u);
    EXPECT_EQ(grid[1].x0, 321);
    EXPECT_EQ(grid[1].x1, 602);
    EXPECT_EQ(grid[3].y1, 452);
    std::vector<int> covered(602 * 452, 0);
    for (const Tile& t : grid)
        for (long y = t.y0; y <= t.y1; ++y)
            for (long x = t.x0; x <= t.x1; ++x) ++covered[std::size_t((y - 1) * 602 + (x - 1))];
    EXPECT_TRUE(std::all_of(covered.begin(), covered.end(), [](int c) { return c == 1; }));
    RandomStream r(3, 0, "tile grid test");
    for (int k = 0; k < 10000; ++k) {
        // Points on the field's pixel area, edges and pixel boundaries included.
        double x = 0.5 + 602.0 * r.uniform(), y = 0.5 + 452.0 * r.uniform();
        if (k % 4 == 0) x = std::floor(x) + 0.5;
        if (k % 8 == 0) y = std::floor(y) + 0.5;
        x = std::min(x, 602.4999);
        y = std::min(y, 452.4999);
        const auto owners = std::count_if(grid.begin(), grid.end(), [&](const Tile& t) { return t.owns(x, y); });
        ASSERT_EQ(owners, 1) << x << ", " << y;
    }
    EXPECT_EQ(tile_grid(100, 100, 100, 100).size(), 1u);
    EXPECT_EQ(tile_grid(100, 100, 1000, 7).size(), 15u);
    EXPECT_THROW(tile_grid(100, 100, 0, 10), Error);
}

// --tile-grid's lines: column, row, then the tile's --tile arguments; a failed stream names
// its sink.
TEST(Sample, TileGridLines) {
    std::ostringstream out;
    write_tile_grid(out, "out", 602, 452, 320, 240);
    EXPECT_EQ(out.str(), "0 0 1 1 320 240\n1 0 321 1 602 240\n0 1 1 241 320 452\n"
                         "1 1 321 241 602 452\n");
    std::ostringstream failed;
    failed.setstate(std::ios::badbit);
    EXPECT_THROW(write_tile_grid(failed, "out", 10, 10, 5, 5), Error);
}

// The run's summary line, field and counts in the order shapesim-sample logs them.
TEST(Sample, SummaryDescribesTheDraw) {
    SampleSummary s;
    s.galaxies = 12;
    s.stars = 3;
    s.galaxies_out = 5;
    s.stars_out = 1;
    s.cells = 4;
    s.cells_read = 2;
    s.redraws = 7;
    const FieldGeometry f = test_field(300, 150);
    const std::string d = s.describe(f, 700.0, true);
    EXPECT_EQ(d.rfind("12 galaxies and 3 stars over ", 0), 0u) << d;
    EXPECT_NE(d.find(" arcmin^2 (700 per arcmin^2; 300 x 150 pixels); 5 galaxies and 1 stars "
                     "written (in the tile) from 2 of 4 sky cells; 7 perturbations redrawn; "),
              std::string::npos) << d;
    EXPECT_EQ(s.describe(f, 700.0, false).find("(in the tile)"), std::string::npos);
}

// Without recorded fields the model leaves the density alone; with --counts parents it
// fits nothing. No point of a plain model is shape-only.
TEST(Sample, ModelCountsWithoutFieldsKeepTheDensity) {
    const Morphology m = test_morphology();
    ASSERT_TRUE(m.source_fields.empty());
    SampleOptions o = crowded_options(1);
    apply_model_counts(o, m, CountSource::parents, false, "model.json");
    EXPECT_EQ(o.density, 3000.0);
    EXPECT_FALSE(o.draw.counts.has_value());
    EXPECT_EQ(count_shape_only(m), 0);
}

// The bright end's clones: the largest share of one parent below each limit, ties to the
// smallest id, stars and parentless records ignored.
TEST(ParentSharesTest, CountsTheCommonestParentBelowEachLimit) {
    ParentShares shares({22.0, 24.0});
    auto galaxy = [](double mag, const char* parent) {
        ObjectRecord r;
        r.mag = mag;
        r.parent = parent;
        return r;
    };
    for (const auto& r : {galaxy(21, "7"), galaxy(21.5, "3"), galaxy(23, "7"), galaxy(23, "9"),
                          galaxy(23.5, "9"), galaxy(23.9, "9"), galaxy(25, "7")})
        shares.add(r);
    ObjectRecord star = galaxy(20, "7");
    star.kind = "star";
    shares.add(star);
    ObjectRecord orphan;
    orphan.mag = 20.0;
    shares.add(orphan);
    const auto s = shares.shares();
    ASSERT_EQ(s.size(), 2u);
    EXPECT_EQ(s[0].galaxies, 2u);
    EXPECT_EQ(s[0].largest, 1u);
    EXPECT_EQ(s[0].parent, "3");
    EXPECT_EQ(s[1].galaxies, 6u);
    EXPECT_EQ(s[1].largest, 3u);
    EXPECT_EQ(s[1].parent, "9");
    EXPECT_EQ(shares.summary(), "I < 22: 1/2 from 3; I < 24: 3/6 from 9");
}

// Several bands (issue 17): each object carries every band, its colours the parent's in δ mode
// whatever the run's zero point (band b's zero point moves with the reference's), and stars a
// flat spectrum.
TEST(Sample, MultiBandObjectsKeepTheirParentsColours) {
    std::vector<ShapeletRecord> records;
    std::map<std::string, double> colour;  // parent id → m_b − m_ref
    for (int i = 0; records.size() < 12; ++i) {
        ShapeletModel m = test::random_model(i % 5, 1.5 + 0.1 * i, 0.0, 0.0, 700 + i, true, 0.2);
        m.coeffs[0] = 1.0 + 0.2 * i;
        if (flux(m) <= 0.0) continue;
        ShapeletRecord r = ShapeletRecord::from_model(m, 0.04, "p" + std::to_string(i));
        r.mag = 25.0 - 2.5 * std::log10(flux(m));
        r.extra["zero_point"] = 25.0;
        ShapeletModel other = m;
        for (Complex& c : other.coeffs) c *= 0.3 + 0.05 * i;
        for (const auto& [name, model, zp] : {std::tuple{"ref", &m, 25.0}, std::tuple{"u", &other, 23.5}}) {
            BandCoefficients b;
            b.band = name;
            b.coeffs = model->coeffs;
            b.flux = flux(*model);
            b.extra["zero_point"] = zp;
            r.bands.push_back(b);
        }
        colour[r.id] = (23.5 - 2.5 * std::log10(flux(other))) - *r.mag;
        records.push_back(r);
    }
    SmoothOptions delta;
    delta.delta = true;
    const Morphology morph = build_morphology(records, delta);
    SampleOptions o = crowded_options(21);
    o.zero_point = 27.0;  // two magnitudes off the real reference: band u's is then 25.5
    long galaxies = 0, stars = 0;
    sample_field(morph, test_field(300, 300), o, std::nullopt, [&](const ObjectRecord& r) {
        ASSERT_EQ(r.bands.size(), 2u);
        EXPECT_EQ(r.bands[0].band, "ref");
        EXPECT_DOUBLE_EQ(r.bands[1].extra.at("zero_point").get<double>(), 25.5);
        EXPECT_DOUBLE_EQ(r.bands[0].extra.at("zero_point").get<double>(), 27.0);
        if (r.kind == "star") {
            ++stars;
            EXPECT_TRUE(r.bands[1].coeffs.empty());
            EXPECT_DOUBLE_EQ(*r.bands[1].mag, *r.mag);
            EXPECT_NEAR(r.bands[1].flux.value(), std::pow(10.0, -0.4 * (*r.mag - 25.5)), 1e-12 * r.bands[1].flux.value());
            return;
        }
        ++galaxies;
        EXPECT_NEAR(*r.bands[0].mag, *r.mag, 1e-12);
        EXPECT_NEAR(*r.bands[1].mag - *r.mag, colour.at(*r.parent), 1e-9);
        EXPECT_EQ(r.bands[0].coeffs, r.coeffs);
        // The record reads back and renders in either band.
        const ObjectRecord u = ObjectRecord::from_json(r.to_json()).in_band("u");
        EXPECT_EQ(u.flux, *r.bands[1].flux);
    });
    EXPECT_GT(galaxies, 50);
    EXPECT_GT(stars, 2);
}

// The sky's unresolved galaxies (SampleOptions::faint_limit): a field of parents to I = 27.8
// counted over 0.1 arcmin², drawn to 27 with galaxies to 29.5 below the limit. Those follow the
// fitted counts extrapolated (their number Poisson about the fit's density on (27, 29.5], their
// magnitudes by KS against its power law), each a scaled copy of one of the faintest parents in
// δ mode and a mixture otherwise, with ids u<k> and below_limit; the galaxies above the limit
// are the same records as without them; a 3×3 tiling gives the whole field; a model without
// fields is refused.
TEST(Sample, GalaxiesBelowTheLimitFollowTheExtrapolatedCounts) {
    Morphology m = test_morphology();
    SourceField field;
    field.area_arcmin2 = 0.1;
    for (const MorphologyPoint& p : m.points) field.mags.push_back(p.mag);
    std::sort(field.mags.begin(), field.mags.end());
    m.source_fields = {field};
    const FieldGeometry f = test_field(1500, 1500);  // 1 arcmin²
    SampleOptions o;
    o.seed = 5;
    o.zero_point = 25.0;
    o.mag_limit = 27.0;
    o.density = 300.0;
    o.draw.neighbours = 4;
    o.draw.mix = 3;
    SampleOptions faint = o;
    faint.faint_limit = 29.5;
    apply_model_counts(faint, m, CountSource::parents, true, "model");
    ASSERT_TRUE(faint.faint_counts);
    const CountModel counts = *faint.faint_counts;
    EXPECT_EQ(counts.bright, 27.0);
    EXPECT_EQ(counts.faint, 29.5);
    std::map<std::string, std::string> plain, with;
    std::vector<double> mags;
    int mixed = 0;
    sample_field(m, f, o, std::nullopt, [&](const ObjectRecord& r) { plain[r.id] = r.to_json().dump(); });
    const SampleSummary s = sample_field(m, f, faint, std::nullopt, [&](const ObjectRecord& r) {
        const Json j = r.to_json();
        with[r.id] = j.dump();
        if (r.id[0] != 'u') return;
        EXPECT_TRUE(j.at("below_limit").get<bool>());
        EXPECT_GT(*r.mag, 27.0);
        EXPECT_LE(*r.mag, 29.5);
        // The window: the 4 parents nearest, those within 2 mag (the nearest always).
        EXPECT_GE(j.at("parents").size(), 1u) << r.id;
        EXPECT_LE(j.at("parents").size(), 3u) << r.id;
        mixed += j.at("parents").size() > 1;
        EXPECT_NEAR(flux(r.to_model(0.0, 0.0)), r.flux, 1e-10 * r.flux) << r.id;
        mags.push_back(*r.mag);
    });
    for (const auto& [id, text] : plain) EXPECT_EQ(with.at(id), text) << id;
    EXPECT_EQ(with.size(), plain.size() + mags.size());
    const double expected = counts.density(27.0, 29.5) * f.area_arcmin2();
    EXPECT_EQ(double(s.faint), double(mags.size()));
    EXPECT_NEAR(double(mags.size()), expected, 4.0 * std::sqrt(expected));
    std::sort(mags.begin(), mags.end());
    double d = 0.0;
    const double n = double(mags.size());
    const auto cdf = [&](double mag) {
        return (std::pow(10.0, counts.slope * (mag - 27.0)) - 1.0) /
               (std::pow(10.0, counts.slope * 2.5) - 1.0);
    };
    for (std::size_t i = 0; i < mags.size(); ++i)
        d = std::max({d, std::abs(cdf(mags[i]) - double(i) / n), std::abs(double(i + 1) / n - cdf(mags[i]))});
    std::cout << "  [measured] " << mags.size() << " galaxies below the limit (fit expects " << expected
              << "), slope " << counts.slope << ", KS distance " << d << "\n";
    ASSERT_GT(n, 150.0);
    EXPECT_LT(d, 1.63 / std::sqrt(n));  // the 1% critical value
    EXPECT_GT(mixed, 50);

    // Tiles: every tile's records are the whole field's, their union is the whole field.
    std::map<std::string, std::string> merged;
    for (int j = 0; j < 3; ++j)
        for (int i = 0; i < 3; ++i) {
            const Tile t{1 + 500 * i, 1 + 500 * j, 500 * (i + 1), 500 * (j + 1)};
            sample_field(m, f, faint, t, [&](const ObjectRecord& r) {
                const std::string text = r.to_json().dump();
                EXPECT_EQ(text, with.at(r.id)) << r.id;
                merged[r.id] = text;
            });
        }
    EXPECT_EQ(merged, with);

    // δ mode: a copy of a faint parent, scaled to its magnitude as L^0.3.
    Morphology dm = m;
    dm.lambda = SmoothingLengths{};
    dm.lambda.phase_deg = 0.0;
    dm.lambda.coefficient.assign(m.lambda.coefficient.size(), 0.0);
    ASSERT_TRUE(dm.lambda.is_delta());
    int copies = 0;
    sample_field(dm, f, faint, std::nullopt, [&](const ObjectRecord& r) {
        if (r.id[0] != 'u') return;
        const Json j = r.to_json();
        EXPECT_EQ(j.at("parents").size(), 1u);
        ++copies;
    });
    EXPECT_GT(copies, 150);

    Morphology bare = m;
    bare.source_fields.clear();
    SampleOptions refused = o;
    refused.faint_limit = 29.5;
    EXPECT_THROW(apply_model_counts(refused, bare, CountSource::parents, true, "model"), Error);
    refused.faint_limit = 26.0;  // not below the limit
    refused.faint_counts = counts;
    EXPECT_THROW(refused.validate(), Error);
}

// The real fields' star counts (smooth --stars): stars brighter than the limit over the area
// of the fields that counted them, in 0.5-mag bins from the brightest; none when no field
// counted, density 0 when the counting fields hold none.
TEST(FieldStarCounts, TheCountingFieldsStarsPerArcmin2InHalfMagnitudeBins) {
    SourceField counted, uncounted;
    counted.area_arcmin2 = 2.0;
    counted.star_mags = std::vector<double>{20.1, 20.2, 21.7, 30.0};
    uncounted.area_arcmin2 = 5.0;
    EXPECT_FALSE(field_star_counts({uncounted}, 29.0));
    const std::optional<StarCounts> s = field_star_counts({counted, uncounted}, 29.0);
    ASSERT_TRUE(s);
    EXPECT_DOUBLE_EQ(s->density, 1.5);  // 3 stars brighter than 29 over 2 arcmin²
    ASSERT_EQ(s->bins.size(), 4u);
    EXPECT_DOUBLE_EQ(s->bins[0].lo, 20.0);
    EXPECT_DOUBLE_EQ(s->bins[0].count, 2.0);
    EXPECT_DOUBLE_EQ(s->bins[1].count, 0.0);
    EXPECT_DOUBLE_EQ(s->bins[3].lo, 21.5);
    EXPECT_DOUBLE_EQ(s->bins[3].count, 1.0);
    EXPECT_DOUBLE_EQ(s->mag_min, 20.0);
    EXPECT_DOUBLE_EQ(s->mag_max, 22.0);
    EXPECT_NO_THROW(s->validate());
    // Every drawn magnitude lies in a bin holding a star.
    for (double u = 0.0; u < 1.0; u += 0.01) {
        const double m = s->magnitude(u);
        EXPECT_TRUE((m >= 20.0 && m < 20.5) || (m >= 21.5 && m <= 22.0)) << m;
    }
    // A limit inside the last bin closes it there; none brighter: density 0.
    const auto cut = field_star_counts({counted}, 21.8);
    EXPECT_DOUBLE_EQ(cut->bins.back().hi, 21.8);
    EXPECT_DOUBLE_EQ(field_star_counts({counted}, 19.0)->density, 0.0);
    SourceField empty = uncounted;
    empty.star_mags = std::vector<double>{};
    EXPECT_DOUBLE_EQ(field_star_counts({empty}, 29.0)->density, 0.0);
}

// Rings (shape-noise cancellation): rings of 4 copies of one draw, copy m turned by m·45°, each
// at its own position; the intrinsic ellipticities (χ of the models' moments) of every ring sum
// to zero, so the mean over ~360 galaxies is ~1e-16 where random orientations leave ~1e-2; the
// copies keep the draw's magnitude, flux and parents; sky cells draw whole rings; a tiling
// gives the whole field's records; an exact count must be a multiple of the ring.
TEST(Sample, RingsCancelTheIntrinsicEllipticity) {
    const Morphology m = test_morphology();
    const FieldGeometry f = test_field(600, 450);
    SampleOptions o = crowded_options(5);
    o.stars.density = 0.0;
    o.cell = 128;  // 20 cells, each drawing whole rings
    o.ring = 4;
    std::map<std::string, std::vector<ObjectRecord>> rings;
    Complex sum_ring = 0.0, sum_plain = 0.0;
    std::size_t n = 0;
    sample_field(m, f, o, std::nullopt, [&](const ObjectRecord& r) {
        rings[r.extra.at("ring").at("first").get<std::string>()].push_back(r);
        sum_ring += moments(r.to_model(0.0, 0.0)).chi;
        ++n;
    });
    ASSERT_GT(n, 300u);
    for (const auto& [first, members] : rings) {
        ASSERT_EQ(members.size(), 4u) << first;
        Complex chi = 0.0;
        for (std::size_t k = 0; k < members.size(); ++k) {
            const ObjectRecord& r = members[k];
            EXPECT_EQ(r.extra.at("ring").at("member").get<int>(), int(k)) << first;
            EXPECT_EQ(*r.mag, *members[0].mag);
            EXPECT_EQ(r.flux, members[0].flux);
            EXPECT_EQ(r.parent, members[0].parent);
            chi += moments(r.to_model(0.0, 0.0)).chi;
        }
        EXPECT_LT(std::abs(chi), 1e-12) << first;
    }
    SampleOptions plain = o;
    plain.ring = 1;
    sample_field(m, f, plain, std::nullopt,
                 [&](const ObjectRecord& r) { sum_plain += moments(r.to_model(0.0, 0.0)).chi; });
    EXPECT_LT(std::abs(sum_ring) / double(n), 1e-14);
    EXPECT_GT(std::abs(sum_plain) / double(n), 1e-3);
    // Tiles: the union of a 2 × 2 tiling is the whole field.
    std::map<std::string, std::string> merged;
    for (int j = 0; j < 2; ++j)
        for (int i = 0; i < 2; ++i)
            for (const auto& [id, text] :
                 draw(m, f, o, Tile{1 + 300 * i, 1 + 225 * j, 300 * (i + 1), 225 * (j + 1)}))
                merged[id] = text;
    EXPECT_EQ(merged, draw(m, f, o, std::nullopt));
    o.count = 1002;
    EXPECT_THROW(o.validate(), Error);
    o.count = 1000;
    std::size_t exact = 0;
    sample_field(m, f, o, std::nullopt, [&](const ObjectRecord&) { ++exact; });
    EXPECT_EQ(exact, 1000u);
}

// The field replayed: every galaxy fit with light becomes an object at its fitted centre, its
// coefficients, flux, magnitude, β and frame as fitted and its sky position through the field's
// WCS; stars and fits without light are counted and left out; a tile keeps the fits reaching
// it; a fit of another pixel scale, or centred beyond its reach from the field, is refused.
TEST(Sample, ReplayWritesEachFitWhereItWasFitted) {
    const FieldGeometry f = test_field(200, 100);
    auto fit = [](std::string id, double x, double y, double flux) {
        ShapeletRecord r;
        r.id = std::move(id);
        r.x = x;
        r.y = y;
        r.beta = 0.12;
        r.pixel_scale = 0.04;
        r.n_max = 2;
        r.coeffs = {{flux / (2.0 * std::sqrt(pi) * 3.0), 0.0}, {0.01, -0.02}, {0.003, 0.0},
                    {0.001, 0.0}, {0.0, 0.002}, {-0.004, 0.0}};
        r.flux = flux;
        r.mag = 25.0 - 2.5 * std::log10(flux);
        return r;
    };
    std::vector<ShapeletRecord> fits = {fit("a", 20.25, 30.5, 2.0), fit("b", 180.0, 90.0, 1.0),
                                        fit("star", 50.0, 50.0, 5.0), fit("dark", 60.0, 60.0, 0.0),
                                        fit("edge", -1.0, 50.0, 1.0)};
    fits[1].extra["frame"] = "intrinsic";
    fits[1].extra["psf_beta"] = 0.07;
    fits[2].extra["kind"] = "star";
    std::vector<ObjectRecord> out;
    const ReplaySummary s =
        replay_field(fits, f, 2.0, std::nullopt, [&](const ObjectRecord& o) { out.push_back(o); });
    EXPECT_EQ(s.written, 3);
    EXPECT_EQ(s.stars, 1);
    EXPECT_EQ(s.no_light, 1);
    ASSERT_EQ(out.size(), 3u);
    for (std::size_t k : {0u, 1u}) {
        const ObjectRecord& o = out[k];
        const ShapeletRecord& r = fits[k];
        EXPECT_EQ(o.id, r.id);
        EXPECT_EQ(*o.parent, r.id);
        EXPECT_EQ(*o.x, r.x);
        EXPECT_EQ(*o.y, r.y);
        EXPECT_EQ(o.coeffs, r.coeffs);
        EXPECT_EQ(o.flux, *r.flux);
        EXPECT_EQ(*o.mag, *r.mag);
        EXPECT_EQ(o.beta, r.beta);
        EXPECT_EQ(o.n_max, r.n_max);
        const PixelPosition p = f.wcs.sky_to_pixel(o.ra, o.dec);
        EXPECT_NEAR(p.x, r.x, 1e-8);
        EXPECT_NEAR(p.y, r.y, 1e-8);
        EXPECT_GT(o.extra.at("reach").get<double>(), 2.0);
    }
    EXPECT_EQ(out[0].extra.at("frame"), "observed");
    EXPECT_FALSE(out[0].extra.contains("psf_beta"));
    EXPECT_EQ(out[1].extra.at("frame"), "intrinsic");
    EXPECT_EQ(out[1].extra.at("psf_beta"), 0.07);

    // A tile of the field's left half: "b" (at x = 180) does not reach it.
    out.clear();
    const ReplaySummary t = replay_field(fits, f, 2.0, Tile{1, 1, 100, 100},
                                         [&](const ObjectRecord& o) { out.push_back(o); });
    EXPECT_EQ(t.written, 2);
    EXPECT_EQ(t.outside_tile, 1);

    std::vector<ShapeletRecord> other = {fit("c", 20.0, 20.0, 1.0)};
    other[0].pixel_scale = 0.06;
    EXPECT_THROW(replay_field(other, f, 2.0, std::nullopt, [](const ObjectRecord&) {}), Error);
    std::vector<ShapeletRecord> far = {fit("d", 20.0, 500.0, 1.0)};
    try {
        replay_field(far, f, 2.0, std::nullopt, [](const ObjectRecord&) {});
        ADD_FAILURE() << "a fit far outside the field was replayed";
    } catch (const Error& e) {
        EXPECT_EQ(e.field(), "x");
        EXPECT_NE(e.message().find("fit d is centred at (20, 500)"), std::string::npos)
            << e.message();
    }
}
