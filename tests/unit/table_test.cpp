// Catalogue tables (table.hpp): JSON-lines records as typed columns with units, and ECSV.
#include "shapesim/table.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/records.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <sstream>

using namespace shapesim;

namespace {

CatalogueTable table_of(const std::string& lines, const std::string& flux_unit = {}) {
    std::istringstream in(lines);
    JsonlReader reader(in, "t.jsonl", {});
    return read_table(reader, flux_unit);
}

const CatalogueColumn& column(const CatalogueTable& t, const std::string& name) {
    for (const CatalogueColumn& c : t.columns)
        if (c.name == name) return c;
    throw Error("no column " + name);
}

}  // namespace

TEST(CatalogueTable, TypesNullsUnitsAndFlattening) {
    const CatalogueTable t = table_of(
        R"({"schema":"s/1","id":"a","x":1,"n":3,"flux":2.5,"ok":true,"psf":{"beta":0.5},"flags":["p","q"],"coeffs":[[1,0]]})"
        "\n"
        R"({"schema":"s/1","id":"b c","x":1.5,"n":4,"flux":null,"ok":false,"flags":[],"new":7})"
        "\n",
        "electron/s");
    EXPECT_EQ(t.schema, "s/1");
    EXPECT_EQ(t.rows, 2);
    ASSERT_EQ(t.skipped, std::vector<std::string>{"coeffs"});
    std::vector<std::string> names;
    for (const auto& c : t.columns) names.push_back(c.name);
    EXPECT_EQ(names, (std::vector<std::string>{"id", "x", "n", "flux", "ok", "psf_beta", "flags", "new"}));
    using Type = CatalogueColumn::Type;
    EXPECT_EQ(column(t, "x").type, Type::real);  // 1 then 1.5
    EXPECT_EQ(column(t, "n").type, Type::integer);
    EXPECT_EQ(column(t, "ok").type, Type::boolean);
    EXPECT_EQ(column(t, "new").type, Type::real);  // an integer with a null before it
    EXPECT_TRUE(std::isnan(column(t, "new").numbers[0]));
    EXPECT_EQ(column(t, "new").numbers[1], 7.0);
    EXPECT_TRUE(std::isnan(column(t, "flux").numbers[1]));
    EXPECT_TRUE(std::isnan(column(t, "psf_beta").numbers[1]));
    EXPECT_EQ(column(t, "flags").texts, (std::vector<std::string>{"p,q", ""}));
    EXPECT_EQ(column(t, "flux").unit, "electron/s");
    EXPECT_EQ(column(t, "x").unit, "pix");
    EXPECT_EQ(column(t, "psf_beta").unit, "arcsec");
    EXPECT_EQ(column(t, "n").unit, "");

    std::ostringstream ecsv;
    write_ecsv(ecsv, t);
    const std::string text = ecsv.str();
    EXPECT_EQ(text.rfind("# %ECSV 1.0\n# ---\n# datatype:\n# - {name: id, datatype: string}\n", 0), 0u);
    EXPECT_NE(text.find("# - {name: flux, unit: electron/s, datatype: float64}\n"), std::string::npos);
    EXPECT_NE(text.find("\na 1 3 2.5 True 0.5 p,q nan\n\"b c\" 1.5 4 nan False nan \"\" 7\n"),
              std::string::npos)
        << text;
}

TEST(CatalogueTable, RefusesWhatOneTableCannotHold) {
    auto fails = [](const std::string& lines, const std::string& want) {
        try {
            table_of(lines);
            ADD_FAILURE() << "no error for " << lines;
        } catch (const Error& e) {
            EXPECT_NE(std::string(e.what()).find(want), std::string::npos) << e.what();
        }
    };
    fails("{\"schema\":\"a/1\",\"id\":\"x\"}\n{\"schema\":\"b/1\",\"id\":\"y\"}\n",
          "t.jsonl:2: schema: schema b/1 in a table of a/1");
    fails("{\"schema\":\"a/1\",\"v\":1}\n{\"schema\":\"a/1\",\"v\":\"t\"}\n", "t.jsonl:2: v: text in a column of numbers");
    fails("{\"schema\":\"a/1\",\"v\":true}\n{\"schema\":\"a/1\",\"v\":2}\n", "t.jsonl:2: v: a number in a column of booleans");
    fails("{\"schema\":\"a/1\",\"v\":9007199254740993}\n", "v: integer beyond 2^53");
    fails("{\"schema\":\"a/1\",\"p_q\":1,\"p\":{\"q\":2}}\n", "p_q: the field appears twice");
}

TEST(CatalogueTable, FitsTableRoundTrip) {
    const CatalogueTable t = table_of(
        R"({"schema":"shapesim.truth/1","id":"g1","x":2.5,"n":3,"kind":"galaxy"})"
        "\n"
        R"({"schema":"shapesim.truth/1","id":"s22","x":-1,"n":0,"kind":"star"})"
        "\n");
    const std::string path = ::testing::TempDir() + "table_test.fits";
    FitsWriter w(path, "table_test");
    write_fits_table(w, t, "TRUTH");
    w.commit();
    FitsReader r(path);
    r.move_to("TRUTH");
    EXPECT_EQ(r.table_rows(), 2);
    EXPECT_EQ(r.read_column("x"), (std::vector<double>{2.5, -1.0}));
    EXPECT_EQ(r.read_column("n"), (std::vector<double>{3.0, 0.0}));
    EXPECT_EQ(r.read_text_column("id"), (std::vector<std::string>{"g1", "s22"}));
    EXPECT_EQ(r.read_text_column("kind"), (std::vector<std::string>{"galaxy", "star"}));
    EXPECT_EQ(r.required_string("TUNIT2"), "pix");
    EXPECT_EQ(r.required_string("SCHEMA"), "shapesim.truth/1");
    std::remove(path.c_str());
}
