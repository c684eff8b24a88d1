// records: the four schemas of DESIGN §2 against the real reference fixtures, round trips,
// carried-through unknown fields and every validation error with its field.
#include "shapesim/records.hpp"
#include "shapesim/jsonl.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>

#include <atomic>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>

using namespace shapesim;

namespace {
std::vector<Json> read_lines(const std::string& path, const char* schema) {
    JsonlReader reader(path, {schema});
    std::vector<Json> out;
    Json j;
    while (reader.next(j)) out.push_back(j);
    return out;
}

// The same JSON values, whatever the key order (nlohmann::json sorts its objects).
nlohmann::json unordered(const Json& j) { return nlohmann::json::parse(j.dump()); }

std::string error_of(const Json& j) {
    try {
        ShapeletRecord::from_json(j);
    } catch (const Error& e) {
        return e.what();
    }
    return "no error";
}

Json m03() {
    return Json::parse(
        R"({"schema": "shapesim.shapelet/1", "id": "M03", "family": "galaxy", "x": 8.980915,
        "y": 9.544113, "beta": 0.062257, "pixel_scale": 0.04, "n_max": 2,
        "flux": 4.314323785712176, "flags": ["converged"], "coeffs": [[1.2028, 0.0],
        [0.447001796079, -0.370684576335], [-0.420848881266, 0.0],
        [-0.129068982392, -0.0919279312142]]})");
}
}  // namespace

TEST(ShapeletRecord, ReadsTheReferenceModels) {
    const auto lines = read_lines(test::reference_dir() + "/models.jsonl", ShapeletRecord::schema);
    ASSERT_EQ(lines.size(), 24u);
    std::map<std::string, int> families;
    for (const auto& line : lines) {
        const ShapeletRecord r = ShapeletRecord::from_json(line);
        ASSERT_EQ(int(r.coeffs.size()), polar_count(r.n_max)) << r.id;
        EXPECT_EQ(r.pixel_scale, 0.04);
        EXPECT_FALSE(r.chi2r);  // optional fields the fixtures omit
        EXPECT_FALSE(r.mag);
        ASSERT_TRUE(r.flux);
        EXPECT_EQ(r.flags, std::vector<std::string>{"converged"});
        ++families[r.extra.at("family").get<std::string>()];
        // Carried through: written back, the record holds the same values.
        EXPECT_EQ(unordered(r.to_json()), unordered(line)) << r.id;
        EXPECT_EQ(r.to_json().begin().key(), "schema");
        EXPECT_EQ(std::next(r.to_json().begin()).key(), "id");
    }
    EXPECT_EQ(families, (std::map<std::string, int>{{"galaxy", 18}, {"random", 4}, {"round", 2}}));
}

TEST(ShapeletRecord, ModelConversionMatchesTheFixtureConventions) {
    const auto lines = read_lines(test::reference_dir() + "/models.jsonl", ShapeletRecord::schema);
    for (const auto& line : lines) {
        const ShapeletRecord r = ShapeletRecord::from_json(line);
        const ShapeletModel model = r.to_model();
        // beta_pix = beta / pixel_scale in double, bit for bit (the fixture README's rule).
        EXPECT_EQ(model.beta_pix, line["beta"].get<double>() / line["pixel_scale"].get<double>());
        EXPECT_EQ(model.x, r.x);
        EXPECT_EQ(model.coeffs, r.coeffs);
        // Flux recomputed from the coefficients equals the stored flux to rounding
        // (a few ulp of the terms: the sum has up to 11 terms of either sign).
        const ShapeletRecord back = ShapeletRecord::from_model(model, r.pixel_scale, r.id);
        double scale = 0.0;
        for (int n = 0; n <= r.n_max; n += 2) scale += std::abs(model.at(n, 0).real());
        scale *= 2.0 * std::sqrt(M_PI) * model.beta_pix;
        EXPECT_NEAR(*back.flux, *r.flux, 1e-15 * scale) << r.id;
        EXPECT_NEAR(back.beta, r.beta, 2.3e-16 * r.beta);  // (β/s)·s: within 1 ulp
        EXPECT_EQ(back.coeffs, r.coeffs);
    }
}

TEST(ReferenceConvolutionRecord, ReadsTheConvolutionFixtures) {
    std::map<std::string, ShapeletRecord> galaxies;
    for (const auto& line :
         read_lines(test::reference_dir() + "/models.jsonl", ShapeletRecord::schema)) {
        const auto r = ShapeletRecord::from_json(line);
        galaxies.emplace(r.id, r);
    }
    const auto lines =
        read_lines(test::reference_dir() + "/convolved.jsonl", ReferenceConvolutionRecord::schema);
    ASSERT_EQ(lines.size(), 8u);
    for (const auto& line : lines) {
        const auto c = ReferenceConvolutionRecord::from_json(line);
        ASSERT_TRUE(galaxies.count(c.galaxy_id)) << c.galaxy_id;
        const ShapeletRecord& g = galaxies.at(c.galaxy_id);
        EXPECT_EQ(c.result.n_max, g.n_max + c.psf.n_max) << c.hdu;
        EXPECT_EQ(c.hdu, c.galaxy_id + "_" + c.psf.id);
        EXPECT_EQ(c.psf.extra.at("family"), "psf");
        EXPECT_EQ(c.result.extra.at("family"), "convolved");
        EXPECT_EQ(c.result.x, c.x);
        EXPECT_NEAR(*c.result.flux, c.flux, 4e-15 * std::abs(c.flux));  // README: ≤ 4e-15
        EXPECT_NEAR(c.flux, *g.flux * *c.psf.flux, 1e-14 * std::abs(c.flux));
        EXPECT_EQ(unordered(c.to_json()), unordered(line));
    }
}

TEST(ReferenceConvolutionRecord, NestedErrorsNameTheirPath) {
    const auto lines =
        read_lines(test::reference_dir() + "/convolved.jsonl", ReferenceConvolutionRecord::schema);
    Json bad = lines.at(0);
    bad["psf"]["beta"] = -1.0;
    try {
        ReferenceConvolutionRecord::from_json(bad);
        FAIL() << "expected Error";
    } catch (const Error& e) {
        EXPECT_EQ(e.field(), "psf.beta");
    }
    bad = lines.at(0);
    bad["result"]["schema"] = "shapesim.source/1";
    try {
        ReferenceConvolutionRecord::from_json(bad);
        FAIL() << "expected Error";
    } catch (const Error& e) {
        EXPECT_EQ(std::string(e.what()),
                  "result.schema: expected \"shapesim.shapelet/1\", got \"shapesim.source/1\"");
    }
}

TEST(ShapeletRecord, ValidationErrorsNameTheField) {
    Json j = m03();
    ASSERT_EQ(error_of(j), "no error");
    j["coeffs"].erase(3);
    EXPECT_EQ(error_of(j), "coeffs: expected 4 [re, im] pairs for n_max 2, got 3");
    j = m03();
    j["coeffs"][2][1] = 0.1;
    EXPECT_EQ(error_of(j), "coeffs[2]: a_{2,0} must be real, got im = 0.10000000000000001");
    j = m03();
    j["coeffs"][1] = Json::array({1.0});
    EXPECT_EQ(error_of(j), "coeffs[1]: expected a [re, im] pair, got [1.0]");
    j = m03();
    j["coeffs"][1][0] = "a";
    EXPECT_EQ(error_of(j), "coeffs[1]: expected a number, got string \"a\"");
    j = m03();
    j["beta"] = -0.3;
    EXPECT_EQ(error_of(j), "beta: must be finite and > 0, got -0.29999999999999999");
    j = m03();
    j["pixel_scale"] = 0;
    EXPECT_EQ(error_of(j), "pixel_scale: must be finite and > 0, got 0");
    j = m03();
    j["n_max"] = -1;
    EXPECT_EQ(error_of(j), "n_max: must be in [0, 200], got -1");
    j = m03();
    j["n_max"] = 2.5;
    EXPECT_EQ(error_of(j), "n_max: expected an integer, got number 2.5");
    j = m03();
    j.erase("beta");
    EXPECT_EQ(error_of(j), "beta: missing");
    j = m03();
    j["x"] = "8.9";
    EXPECT_EQ(error_of(j), "x: expected a number, got string \"8.9\"");
    j = m03();
    j["flags"] = "converged";
    EXPECT_EQ(error_of(j), "flags: expected an array, got string \"converged\"");
    j = m03();
    j["id"] = "";
    EXPECT_EQ(error_of(j), "id: must not be empty");
}

TEST(ShapeletRecord, ReaderPlacesRecordErrors) {
    Json bad = m03();
    bad["beta"] = -0.3;
    std::istringstream in(m03().dump() + "\n\n" + bad.dump() + "\n");
    JsonlReader reader(in, "shapelets.jsonl", {ShapeletRecord::schema});
    ShapeletRecord r;
    ASSERT_TRUE(reader.next_record(r));
    try {
        reader.next_record(r);
        FAIL() << "expected Error";
    } catch (const Error& e) {
        EXPECT_EQ(std::string(e.what()),
                  "shapelets.jsonl:3: beta: must be finite and > 0, got -0.29999999999999999");
    }
}

TEST(ShapeletRecord, ToJsonOrderAndOptionalFields) {
    ShapeletRecord r = ShapeletRecord::from_json(m03());
    r.chi2r = 1.02;
    r.mag = 24.5;
    const std::string text = r.to_json().dump();
    EXPECT_EQ(text.rfind(R"({"schema":"shapesim.shapelet/1","id":"M03","x":8.980915,"y":9.544113,)"
                         R"("beta":0.062257,"pixel_scale":0.04,"n_max":2,"flux":4.314323785712176,)"
                         R"("mag":24.5,"chi2r":1.02,"flags":["converged"],"family":"galaxy",)"
                         R"("coeffs":[[1.2028,0.0],)",
                         0),
              0u)
        << text;
    r.coeffs.pop_back();
    EXPECT_THROW(r.to_json(), Error);  // an inconsistent record is never written
}

TEST(SourceRecord, RoundTripWithExtraAndIntegerId) {
    const Json j = Json::parse(
        R"({"schema": "shapesim.source/1", "id": 17, "x": 101.5, "y": 33.25, "ra": 189.2,
        "dec": 62.21, "flux": 0.0123, "flux_err": 0.0004, "mag": 26.85, "a": 2.5, "b": 1.25,
        "theta": -30.0, "fwhm": 3.1, "stellarity": 0.03, "flags": ["edge"], "area": 41})");
    const SourceRecord r = SourceRecord::from_json(j);
    EXPECT_EQ(r.id, "17");
    EXPECT_EQ(*r.theta, -30.0);
    EXPECT_EQ(r.extra, Json({{"area", 41}}));
    Json expected = j;
    expected["id"] = "17";
    EXPECT_EQ(unordered(r.to_json()), unordered(expected));

    const SourceRecord minimal = SourceRecord::from_json(
        Json::parse(R"({"schema": "shapesim.source/1", "id": "a", "x": 1, "y": 2, "flux": -1})"));
    EXPECT_FALSE(minimal.mag);
    EXPECT_FALSE(minimal.to_json().contains("mag"));  // absent stays absent, never null

    Json bad = j;
    bad["stellarity"] = 1.5;
    EXPECT_THROW(SourceRecord::from_json(bad), Error);
    bad = j;
    bad["dec"] = 91;
    EXPECT_THROW(SourceRecord::from_json(bad), Error);
    bad = j;
    bad["schema"] = "shapesim.object/1";
    EXPECT_THROW(SourceRecord::from_json(bad), Error);
}

// JsonlReader::read_all reads an object's "coeffs" straight into numbers (NumberPairs): every
// line gives what the DOM path (next_record) gives, the record or the same located error —
// integer, signed-zero and exponent coefficients, spacing, counts, shapes and values the DOM
// path refuses, duplicates, stars with and without a shape, unknown fields.
TEST(ObjectRecord, CoefficientsReadStraightEqualTheDom) {
    const std::string head = R"({"schema":"shapesim.object/1","id":"g1","kind":"galaxy","ra":1.5,)"
                             R"("dec":-2.25,"flux":3.0,"beta":0.2,"pixel_scale":0.04,"n_max":2,)";
    const std::vector<std::string> lines = {  // polar order (0,0), (1,1), (2,0), (2,2)
        head + R"("coeffs":[[0.5,0.0],[0.1,-0.2],[0.3,-0.0],[1e-3,-2.5E+2]]})",
        head + R"("coeffs":[[1,0],[0,-2],[-0,-0],[5,6]],"rotation":12.5,"extra":[1,"a"]})",
        head + R"("coeffs": [ [ 1 , 0 ] , [2,3],[4, 0] ,[ 5,6 ] ] ,"parent":"p"})",
        R"({"coeffs":[[1,0],[2,3],[4,0],[5,6]],)" + head.substr(1) + R"("flags":["a"]})",
        head + R"("coeffs":[[1,0],[2,3],[4,0]]})",                 // one pair short
        head + R"("coeffs":[[1,0],[2,3,4],[4,0],[5,6]]})",         // a triple
        head + R"("coeffs":[[1,0],[2,3],[4,0],[5,1e999]]})",       // past double
        head + R"("coeffs":[[1,0],[2,"x"],[4,0],[5,6]]})",         // a string
        head + R"("coeffs":[[1,0.5],[2,3],[4,0],[5,6]]})",         // a_{0,0} not real
        head + R"("coeffs":3})",
        head + R"("coeffs":[]})",
        head + R"("coeffs":[[1,0]],"coeffs":[[1,0]]})",           // duplicate key
        head + R"("coeffs":[[1,0],[2,3],[4,0],[5,6]],"bands":{}})",
        R"({"schema":"shapesim.object/1","id":"s1","kind":"star","ra":1,"dec":2,"flux":3})",
        R"({"schema":"shapesim.object/1","id":"s2","kind":"star","ra":1,"dec":2,"flux":3,)"
        R"("beta":0.1,"pixel_scale":0.04,"n_max":0,"coeffs":[[2,0]]})",
        R"({"schema":"shapesim.object/1","id":"g2","kind":"galaxy","ra":1,"dec":2,"flux":3})",
    };
    auto outcome = [](const std::string& line, bool straight) -> std::string {
        std::istringstream in(line + "\n");
        JsonlReader reader(in, "objects.jsonl", {ObjectRecord::schema});
        try {
            ObjectRecord r;
            if (straight) {
                const std::vector<ObjectRecord> all = reader.read_all<ObjectRecord>(1);
                if (all.size() != 1) return "count " + std::to_string(all.size());
                r = all[0];
            } else if (!reader.next_record(r)) {
                return "none";
            }
            return r.to_json().dump();
        } catch (const Error& e) {
            return std::string("error: ") + e.what();
        }
    };
    int records = 0;
    for (const std::string& line : lines) {
        const std::string dom = outcome(line, false);
        EXPECT_EQ(outcome(line, true), dom) << line;
        records += dom.rfind("error", 0) != 0;
    }
    EXPECT_EQ(records, 6);
}

TEST(ObjectRecord, GalaxiesNeedAShapeStarsDoNot) {
    const Json galaxy = Json::parse(
        R"({"schema": "shapesim.object/1", "id": "g1", "kind": "galaxy", "ra": 189.2,
        "dec": 62.2, "mag": 27.1, "flux": 0.01, "beta": 0.1, "pixel_scale": 0.04,
        "n_max": 1, "parent": "M02", "tile": [0, 3],
        "coeffs": [[0.5, 0.0], [0.01, -0.02]]})");
    const ObjectRecord g = ObjectRecord::from_json(galaxy);
    EXPECT_TRUE(g.has_shape());
    EXPECT_EQ(*g.parent, "M02");
    const ShapeletModel model = g.to_model(10.5, 20.25);
    EXPECT_EQ(model.beta_pix, 0.1 / 0.04);
    EXPECT_EQ(model.x, 10.5);
    Json expected = galaxy;
    expected["flags"] = Json::array();  // flags are always written
    EXPECT_EQ(unordered(g.to_json()), unordered(expected));

    const ObjectRecord star = ObjectRecord::from_json(Json::parse(
        R"({"schema": "shapesim.object/1", "id": "s1", "kind": "star", "ra": 1, "dec": 2,
        "flux": 3})"));
    EXPECT_FALSE(star.has_shape());
    EXPECT_FALSE(star.to_json().contains("coeffs"));
    EXPECT_THROW(star.to_model(1, 1), Error);

    Json bad = galaxy;
    bad.erase("coeffs");
    try {
        ObjectRecord::from_json(bad);
        FAIL() << "expected Error";
    } catch (const Error& e) {
        EXPECT_EQ(e.field(), "coeffs");
    }
    bad = galaxy;
    bad["kind"] = "quasar";
    try {
        ObjectRecord::from_json(bad);
        FAIL() << "expected Error";
    } catch (const Error& e) {
        EXPECT_EQ(std::string(e.what()), "kind: must be \"galaxy\" or \"star\", got \"quasar\"");
    }
}

TEST(MorphRecord, RoundTripAndAbsentStatistics) {
    const Json j = Json::parse(
        R"({"schema": "shapesim.morph/1", "id": "5", "x": 10, "y": 11.5, "mag": 25.2,
        "fwhm": 4.1, "a": 3, "b": 2, "theta": 12.5, "e1": 0.1, "e2": -0.05, "r_petro": 9.5,
        "c": 3.1, "a_sym": 0.18, "s": 0.23, "gini": 0.5, "m20": -1.7, "flags": [],
        "sn": 40.2})");
    const MorphRecord r = MorphRecord::from_json(j);
    EXPECT_EQ(*r.a_sym, 0.18);
    EXPECT_EQ(unordered(r.to_json()), unordered(j));
    const MorphRecord sparse = MorphRecord::from_json(
        Json::parse(R"({"schema": "shapesim.morph/1", "id": "6", "x": 1, "y": 2, "c": null})"));
    EXPECT_FALSE(sparse.c);
    EXPECT_FALSE(sparse.to_json().contains("c"));
}

TEST(Records, NanIsRefusedWhenWrittenNamingFileLineField) {
    SourceRecord r = SourceRecord::from_json(
        Json::parse(R"({"schema": "shapesim.source/1", "id": "a", "x": 1, "y": 2, "flux": 1})"));
    std::ostringstream out;
    JsonlWriter writer(out, "sources.jsonl");
    writer.write(r.to_json());
    r.mag = std::nan("");
    try {
        writer.write(r.to_json());
        FAIL() << "expected Error";
    } catch (const Error& e) {
        EXPECT_EQ(std::string(e.what()),
                  "sources.jsonl:2: mag: is NaN or infinite, which JSON cannot hold");
    }
    r.mag.reset();
    r.x = INFINITY;
    EXPECT_THROW(r.to_json(), Error);  // validate() catches required fields first
}

// Multi-band records (issue 17): `bands` round-trips after the coefficients, each band's
// coefficients are checked as the record's own, and errors name the band's path.
TEST(ShapeletRecord, BandsRoundTripAndNameTheirErrors) {
    Json j = m03();
    j["bands"] = Json::parse(
        R"([{"band": "f435w", "flux": 1.5, "mag": 27.1, "coeff_errors": [[0.1, 0.0]],
             "coeffs": [[0.5, 0.0], [0.1, -0.2], [-0.1, 0.0], [0.0, 0.05]]},
            {"band": "f814w", "flux": 4.3, "flux_err": 0.2,
             "coeffs": [[1.2028, 0.0], [0.447, -0.37], [-0.42, 0.0], [-0.13, -0.09]]}])");
    const ShapeletRecord r = ShapeletRecord::from_json(j);
    ASSERT_EQ(r.bands.size(), 2u);
    EXPECT_EQ(r.bands[0].band, "f435w");
    EXPECT_EQ(r.bands[0].coeffs[1], Complex(0.1, -0.2));
    EXPECT_EQ(*r.bands[1].flux_err, 0.2);
    EXPECT_TRUE(r.bands[0].extra.contains("coeff_errors"));
    const Json back = r.to_json();
    EXPECT_EQ(unordered(back), unordered(j));
    // Written last, after the record's own coefficients.
    std::vector<std::string> keys;
    for (const auto& item : back.items()) keys.push_back(item.key());
    EXPECT_EQ(keys.back(), "bands");
    EXPECT_EQ(keys[keys.size() - 2], "coeffs");

    Json bad = j;
    bad["bands"][1]["coeffs"][2][1] = 0.5;
    EXPECT_EQ(error_of(bad), "bands[1].coeffs[2]: a_{2,0} must be real, got im = 0.5");
    bad = j;
    bad["bands"][0]["coeffs"].erase(0);
    EXPECT_EQ(error_of(bad), "bands[0].coeffs: expected 4 [re, im] pairs for n_max 2, got 3");
    bad = j;
    bad["bands"][1]["band"] = "f435w";
    EXPECT_EQ(error_of(bad), "bands[1]: band \"f435w\" appears twice");
    bad = j;
    bad["bands"][0].erase("band");
    EXPECT_EQ(error_of(bad), "bands[0].band: missing");
    bad = j;
    bad["bands"][0]["flux_err"] = -1.0;
    EXPECT_EQ(error_of(bad), "bands[0].flux_err: must be >= 0, got -1");
    bad = j;
    bad["bands"] = Json::object();
    EXPECT_EQ(error_of(bad), "bands: expected an array, got object");
}

TEST(ObjectRecord, InBandTakesThatBandsShapeAndFlux) {
    ObjectRecord o;
    o.id = "g1";
    o.flux = 4.0;
    o.mag = 24.0;
    o.beta = 0.1;
    o.pixel_scale = 0.06;
    o.n_max = 0;
    o.coeffs = {Complex(1.0, 0.0)};
    BandCoefficients b;
    b.band = "f160w";
    b.coeffs = {Complex(3.0, 0.0)};
    b.flux = 12.0;
    b.mag = 23.0;
    o.bands = {b};
    const ObjectRecord red = o.in_band("f160w");
    EXPECT_EQ(red.coeffs[0], Complex(3.0, 0.0));
    EXPECT_EQ(red.flux, 12.0);
    EXPECT_EQ(*red.mag, 23.0);
    EXPECT_TRUE(red.bands.empty());
    EXPECT_EQ(red.beta, o.beta);
    EXPECT_THROW(o.in_band("f435w"), Error);
    const ObjectRecord back = ObjectRecord::from_json(o.to_json());
    ASSERT_EQ(back.bands.size(), 1u);
    EXPECT_EQ(back.bands[0].coeffs[0], Complex(3.0, 0.0));
}

TEST(BandRecord, ReadsTheBandsFileAndRefusesRepeats) {
    const std::string path = ::testing::TempDir() + "bands_test.jsonl";
    {
        std::ofstream f(path);
        f << R"({"schema": "shapesim.band/1", "band": "f435w", "image": "b.fits", "weight": "bw.fits", "zero_point": 25.684})"
          << "\n"
          << R"({"schema": "shapesim.band/1", "band": "f814w", "image": "i.fits", "gain": 50800, "psf": "psf.jsonl"})"
          << "\n";
    }
    const std::vector<BandRecord> bands = BandRecord::read_all(path);
    ASSERT_EQ(bands.size(), 2u);
    EXPECT_EQ(bands[0].weight, "bw.fits");
    EXPECT_EQ(bands[0].weight_type, "weight");
    EXPECT_EQ(*bands[0].zero_point, 25.684);
    EXPECT_EQ(*bands[1].gain, 50800.0);
    EXPECT_EQ(bands[1].psf, "psf.jsonl");
    EXPECT_TRUE(bands[1].weight.empty());
    EXPECT_EQ(BandRecord::from_json(bands[0].to_json()).to_json(), bands[0].to_json());
    {
        std::ofstream f(path, std::ios::app);
        f << R"({"schema": "shapesim.band/1", "band": "f435w", "image": "c.fits"})" << "\n";
    }
    try {
        BandRecord::read_all(path);
        ADD_FAILURE() << "a repeated band was accepted";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find(":3: band: band \"f435w\" appears twice"),
                  std::string::npos)
            << e.what();
    }
    {
        std::ofstream f(path);
        f << R"({"schema": "shapesim.band/1", "band": "x", "image": "c.fits", "weight_type": "sigma"})"
          << "\n";
    }
    EXPECT_THROW(BandRecord::read_all(path), Error);
    { std::ofstream f(path); }
    EXPECT_THROW(BandRecord::read_all(path), Error);
    std::remove(path.c_str());
}

TEST(TruthRecord, WritesRendersKeyOrderAndRoundTrips) {
    // The line shapesim-render has always written: schema, id, kind, ra, dec, x, y, flux,
    // mag, clipped_flux, the galaxy's shape (null where undefined), n_max, stamp_radius.
    TruthRecord t;
    t.id = "g7";
    t.ra = 189.2;
    t.dec = 62.25;
    t.x = 10.5;
    t.y = -3.25;
    t.flux = 0.125;
    t.mag = 24.5;
    t.clipped_flux = 0.0625;
    t.shape = TruthRecord::Shape{0.25, std::nullopt, 1.5, 1e-9, 0.2, std::nullopt};
    t.shape->g1 = 0.05;
    t.shape->kappa = 0.01;
    t.shape->mu = 1.25;
    t.n_max = 12;
    t.stamp_radius = 7.5;
    const Json j = t.to_json();
    EXPECT_EQ(j.dump(),
              R"({"schema":"shapesim.truth/1","id":"g7","kind":"galaxy","ra":189.2,"dec":62.25,)"
              R"("x":10.5,"y":-3.25,"flux":0.125,"mag":24.5,"clipped_flux":0.0625,"e1":0.25,)"
              R"("e2":null,"rms_radius":1.5,"lensing_error":1e-09,"e1_intrinsic":0.2,)"
              R"("e2_intrinsic":null,"g1":0.05,"g2":0.0,"kappa":0.01,"mu":1.25,"n_max":12,)"
              R"("stamp_radius":7.5})");
    const TruthRecord back = TruthRecord::from_json(j);
    EXPECT_EQ(back.to_json().dump(), j.dump());
    ASSERT_TRUE(back.shape);
    EXPECT_EQ(back.shape->e1, 0.25);
    EXPECT_FALSE(back.shape->e2);
    EXPECT_EQ(back.shape->lensing_error, 1e-9);
    EXPECT_EQ(back.shape->e1_intrinsic, 0.2);
    EXPECT_FALSE(back.shape->e2_intrinsic);
    EXPECT_EQ(back.shape->mu, 1.25);
    // A truth line of before the intrinsic shapes: unlensed, e_intrinsic = e.
    Json old = j;
    for (const char* key : {"e1_intrinsic", "e2_intrinsic", "g1", "g2", "kappa", "mu"}) old.erase(key);
    const TruthRecord before = TruthRecord::from_json(old);
    EXPECT_EQ(before.shape->e1_intrinsic, 0.25);
    EXPECT_EQ(before.shape->g1, 0.0);
    EXPECT_EQ(before.shape->mu, 1.0);
    Json bad = j;
    bad["mu"] = -1.0;
    EXPECT_THROW(TruthRecord::from_json(bad), Error);

    // A star: no mag, nothing clipped, no shape; unknown fields carried at the end.
    TruthRecord star;
    star.id = "s1";
    star.kind = "star";
    star.flux = 2.0;
    star.n_max = 6;
    star.stamp_radius = 3.0;
    star.extra["tile"] = "a";
    const std::string line = star.to_json().dump();
    EXPECT_EQ(line, R"({"schema":"shapesim.truth/1","id":"s1","kind":"star","ra":0.0,"dec":0.0,)"
                    R"("x":0.0,"y":0.0,"flux":2.0,"n_max":6,"stamp_radius":3.0,"tile":"a"})");
    EXPECT_EQ(TruthRecord::from_json(Json::parse(line)).to_json().dump(), line);
    EXPECT_FALSE(TruthRecord::from_json(Json::parse(line)).shape);
}

TEST(TruthRecord, ValidationErrorsNameTheField) {
    auto error = [](const std::string& text) {
        try {
            TruthRecord::from_json(Json::parse(text));
        } catch (const Error& e) {
            return e.field();
        }
        return std::string("no error");
    };
    const std::string head = R"({"schema":"shapesim.truth/1","id":"g","ra":1,"dec":2,"x":3,"y":4,)";
    EXPECT_EQ(error(head + R"("kind":"planet","flux":1,"n_max":0,"stamp_radius":1})"), "kind");
    EXPECT_EQ(error(head + R"("kind":"star","flux":1,"n_max":0,"stamp_radius":-1})"), "stamp_radius");
    EXPECT_EQ(error(head + R"("kind":"star","n_max":0,"stamp_radius":1})"), "flux");
    EXPECT_EQ(error(head + R"("kind":"galaxy","flux":1,"e1":0.1,"lensing_error":-1,"n_max":0,)"
                           R"("stamp_radius":1})"), "lensing_error");
    EXPECT_EQ(error(head + R"("kind":"star","flux":1,"clipped_flux":-1,"n_max":0,"stamp_radius":1})"),
              "clipped_flux");
    EXPECT_EQ(error(head + R"("kind":"star","flux":1,"n_max":0,"stamp_radius":1})"), "no error");
}

// A flag, and any one of '|'-separated alternatives.
TEST(Flags, HasFlagAndAlternatives) {
    const std::vector<std::string> flags{"converged", "edge"};
    EXPECT_TRUE(has_flag(flags, "edge"));
    EXPECT_FALSE(has_flag(flags, "holes"));
    EXPECT_TRUE(has_any_flag(flags, "n_max_cap|converged"));
    EXPECT_TRUE(has_any_flag(flags, "edge"));
    EXPECT_FALSE(has_any_flag(flags, "n_max_cap|holes"));
    EXPECT_FALSE(has_any_flag({}, "converged"));
}

// An object with a magnitude and a flux of 0, -0 or a denormal is refused where it is read,
// naming the field (render would otherwise paint the image and fail on the truth's NaN
// magnitude); without a magnitude a zero flux is only an invisible object.
TEST(ObjectRecord, ZeroOrDenormalFluxWithAMagnitudeIsRefused) {
    Json star = Json::parse(R"({"schema": "shapesim.object/1", "id": "s1", "kind": "star",
        "ra": 10.0, "dec": 2.0, "mag": 21.0, "flux": 1.5})");
    EXPECT_NO_THROW(ObjectRecord::from_json(star));
    for (double flux : {0.0, -0.0, 5e-324, -2.0}) {
        star["flux"] = flux;
        try {
            ObjectRecord::from_json(star);
            ADD_FAILURE() << "flux " << flux << " accepted";
        } catch (const Error& e) {
            EXPECT_EQ(e.field(), "flux");
            EXPECT_NE(e.message().find("positive normal number"), std::string::npos) << e.message();
        }
    }
    star.erase("mag");
    star["flux"] = 0.0;
    EXPECT_NO_THROW(ObjectRecord::from_json(star));
}

// read_all holds its lines a chunk at a time: 2.5 chunks of records, blank lines among them,
// come back whole and in order, each with its own line number, on one thread or three, and
// `each` sees every record as it is made; the error thrown is the first bad line's, even when
// a later chunk has another.
TEST(JsonlReaderTest, ReadAllInChunksKeepsOrderLinesAndFirstError) {
    const std::size_t n = 5 * JsonlReader::chunk_lines / 2;
    std::string text;
    for (std::size_t k = 0; k < n; ++k) {
        if (k % 1000 == 0) text += "\n";  // a blank line: the line numbers skip it
        text += R"({"schema":"shapesim.object/1","id":"s)" + std::to_string(k) +
                R"(","kind":"star","ra":1,"dec":2,"flux":3,"rotation":)" + std::to_string(k) + "}\n";
    }
    for (int threads : {1, 3}) {
        std::istringstream in(text);
        JsonlReader reader(in, "objects.jsonl", {ObjectRecord::schema});
        std::vector<long> lines;
        std::atomic<long> seen{0};
        const std::vector<ObjectRecord> all =
            reader.read_all<ObjectRecord>(threads, &lines, [&](ObjectRecord& r) {
                ++seen;
                r.extra.erase("rotation");
            });
        ASSERT_EQ(all.size(), n);
        ASSERT_EQ(lines.size(), n);
        EXPECT_EQ(seen.load(), long(n));
        for (std::size_t k = 0; k < n; k += 997) {
            EXPECT_EQ(all[k].id, "s" + std::to_string(k));
            EXPECT_EQ(lines[k], long(k + k / 1000 + 2));  // k + 1, after k / 1000 + 1 blank lines
            EXPECT_FALSE(all[k].extra.contains("rotation"));
        }
    }
    // Bad lines at 20 000 (second chunk) and 40 000 (third): the first is reported.
    std::string bad = text;
    auto spoil = [&](std::size_t record) {
        const std::string id = R"("id":"s)" + std::to_string(record) + R"(")";
        const std::size_t at = bad.find(id);
        bad.replace(bad.find("\"flux\":3", at), 8, "\"flux\":\"x\"");
    };
    spoil(40000);
    spoil(20000);
    std::istringstream in(bad);
    JsonlReader reader(in, "objects.jsonl", {ObjectRecord::schema});
    try {
        reader.read_all<ObjectRecord>(2);
        FAIL() << "a bad record was read";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("objects.jsonl:" + std::to_string(20000 + 20 + 2)),
                  std::string::npos) << e.what();
    }
}
