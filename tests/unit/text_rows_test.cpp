// Text tables: the lines a reader sees (comments cut, blanks skipped, every line counted), the
// row bound, and the three readers built on them refusing what is not their table.
#include "shapesim/detect.hpp"
#include "shapesim/error.hpp"
#include "shapesim/lensing.hpp"
#include "shapesim/sample.hpp"
#include "shapesim/text_rows.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <functional>
#include <sstream>
#include <utility>
#include <vector>

namespace shapesim {
namespace {

std::vector<std::pair<long, std::string>> rows_of(const std::string& table) {
    std::istringstream in(table);
    std::vector<std::pair<long, std::string>> rows;
    for_each_text_row(in, "t.txt", [&](const std::string& text, long line) {
        rows.emplace_back(line, text);
    });
    return rows;
}

TEST(TextRows, CommentsCutBlanksSkippedEveryLineCounted) {
    const auto rows = rows_of("# mag_lo mag_hi count\n\n18 19 3  # bright\r\n \t \r\n"
                              "   # only a comment\n19 20 7\n20 21 9");
    ASSERT_EQ(rows.size(), 3u);
    EXPECT_EQ(rows[0], std::make_pair(3L, std::string("18 19 3  ")));
    EXPECT_EQ(rows[1], std::make_pair(6L, std::string("19 20 7")));
    EXPECT_EQ(rows[2], std::make_pair(7L, std::string("20 21 9")));  // no final newline
    EXPECT_TRUE(rows_of("").empty());
    EXPECT_TRUE(rows_of("#\n\n   \n").empty());
}

TEST(TextRows, RowsBoundedNamingTheLine) {
    std::string table = "# header\n";
    for (long i = 0; i <= max_text_rows; ++i) table += "1\n";
    try {
        rows_of(table);
        FAIL() << "a table over the bound was read";
    } catch (const Error& e) {
        EXPECT_EQ(e.where_what(), "t.txt:" + std::to_string(max_text_rows + 2) +
                                      ": more than 10^6 rows");
    }
    table.erase(table.size() - 2);  // exactly the bound
    EXPECT_EQ(long(rows_of(table).size()), max_text_rows);
}

TEST(TextRows, ErrorFromARowKeepsItsLine) {
    std::istringstream in("# c\n1\n\nbad\n");
    try {
        for_each_text_row(in, "t.txt", [](const std::string& text, long line) {
            if (text == "bad") throw Error("not a number", "t.txt", line);
        });
        FAIL() << "the row's error was lost";
    } catch (const Error& e) {
        EXPECT_EQ(e.where_what(), "t.txt:4: not a number");
    }
}

std::string refusal(const std::function<void()>& read) {
    try {
        read();
    } catch (const Error& e) {
        return e.where_what();
    }
    return "(read)";
}

// /dev/zero never ends a line: refused once the line passes the bound, not after it has filled
// memory (the JSON-lines reader and the catalogue tables read their lines the same way).
TEST(TextRows, EndlessLineRefusedAtTheBound) {
    std::ifstream zeros("/dev/zero", std::ios::binary);
    ASSERT_TRUE(zeros);
    EXPECT_EQ(refusal([&] { for_each_text_row(zeros, "/dev/zero", [](auto&&...) {}); }),
              "/dev/zero:1: a line longer than 256 MiB: not a text table (no newline?)");
    std::istringstream two("first\nsecond, no newline");
    std::string text;
    ASSERT_TRUE(read_text_line(two, text, "t", 1, "a text table"));
    EXPECT_EQ(text, "first");
    ASSERT_TRUE(read_text_line(two, text, "t", 2, "a text table"));
    EXPECT_EQ(text, "second, no newline");
    EXPECT_FALSE(read_text_line(two, text, "t", 3, "a text table"));
}

// The readers on text tables: what each accepts and the line it names when it refuses.
std::string write_file(const test::TempDir& dir, const std::string& name, const std::string& text) {
    const std::string path = dir.path() + "/" + name;
    std::ofstream(path) << text;
    return path;
}


TEST(TextRows, StarHistogramReadAndRefused) {
    const test::TempDir dir;
    const auto bins = read_star_histogram(
        write_file(dir, "stars.txt", "# mag_lo mag_hi count\n18 19 3\n\n19 20 7 # fainter\n"));
    ASSERT_EQ(bins.size(), 2u);
    EXPECT_EQ(bins[1].lo, 19.0);
    EXPECT_EQ(bins[1].hi, 20.0);
    EXPECT_EQ(bins[1].count, 7.0);
    // A header without '#' was once skipped as if blank: now it is named.
    const std::string header = write_file(dir, "header.txt", "mag_lo mag_hi count\n18 19 3\n");
    EXPECT_EQ(refusal([&] { read_star_histogram(header); }),
              header + ":1: expected three numbers: mag_lo mag_hi count");
    const std::string short_row = write_file(dir, "short.txt", "18 19 3\n# c\n19 20\n");
    EXPECT_EQ(refusal([&] { read_star_histogram(short_row); }),
              short_row + ":3: expected three numbers: mag_lo mag_hi count");
    const std::string empty = write_file(dir, "empty.txt", "# nothing\n");
    EXPECT_EQ(refusal([&] { read_star_histogram(empty); }), empty + ": no bins");
}

TEST(TextRows, PowerSpectrumReadAndRefused) {
    const test::TempDir dir;
    const PowerSpectrum p =
        read_power_spectrum(write_file(dir, "p.txt", "# ell P\n10 1e-6\n\n100 1e-8 # knee\n"));
    EXPECT_DOUBLE_EQ(p(10.0), 1e-6);
    EXPECT_DOUBLE_EQ(p(100.0), 1e-8);
    const std::string words = write_file(dir, "words.txt", "10 1e-6\nell P\n");
    EXPECT_EQ(refusal([&] { read_power_spectrum(words); }),
              words + ":2: expected two numbers: ell P(ell)");
    const std::string three = write_file(dir, "three.txt", "10 1e-6 5\n");
    EXPECT_EQ(refusal([&] { read_power_spectrum(three); }),
              three + ":1: expected two numbers: ell P(ell)");
}

TEST(TextRows, FilterKernelCommentsAndLines) {
    std::istringstream in("# a 3x3 filter\nCONV NORM\n# weights\n1 2 1\n\n2 4 2 # middle\n1 2 1\n");
    const FilterKernel k = parse_filter_kernel(in, "f.conv");
    EXPECT_EQ(k.nx, 3);
    EXPECT_EQ(k.ny, 3);
    EXPECT_EQ(k.values, (std::vector<float>{1, 2, 1, 2, 4, 2, 1, 2, 1}));
    std::istringstream ragged("CONV NORM\n1 2 1\n# c\n2 4\n");
    EXPECT_EQ(refusal([&] { parse_filter_kernel(ragged, "f.conv"); }),
              "f.conv:4: row has 2 values, the first had 3");
}

}  // namespace
}  // namespace shapesim
