// fits_io: reading the real HDF-N and reference files, the (j, i) ↔ (y, x) convention, MEF
// writing round trips, and every bad-input class with the place it names.
#include "shapesim/version.hpp"
#include "shapesim/fits_io.hpp"

#include "shapesim/error.hpp"
#include "shapesim/rng.hpp"
#include "test_support.hpp"

#include <fitsio.h>
#include <gtest/gtest.h>

#include <array>

#include <cmath>
#include <cstring>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>

using namespace shapesim;
namespace fs = std::filesystem;

namespace {

// The shipped HDF-N data: $SHAPESIM_DATA/hdfn, else share/data/hdfn of this repository.
std::string hdfn_dir() {
    if (const char* env = std::getenv("SHAPESIM_DATA"))
        if (fs::is_directory(std::string(env) + "/hdfn")) return std::string(env) + "/hdfn";
    return fs::path(__FILE__).parent_path().parent_path().parent_path() / "share/data/hdfn";
}

class FitsTest : public ::testing::Test {
protected:
    void SetUp() override {
        char pattern[] = "/tmp/shapesim-fits-XXXXXX";
        ASSERT_NE(mkdtemp(pattern), nullptr);
        dir_ = pattern;
    }
    void TearDown() override { fs::remove_all(dir_); }
    std::string path(const std::string& name) const { return dir_ + "/" + name; }
    std::size_t file_count() const {
        return std::distance(fs::directory_iterator(dir_), fs::directory_iterator());
    }
    std::string dir_;
};

// A test image whose pixel value tells its indices: 1000 j + i (+ a fraction).
ImageArray index_image(int ny, int nx) {
    ImageArray image(ny, nx);
    for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) image(j, i) = 1000.0 * j + i + 0.125;
    return image;
}

// The Error thrown by `f`, or a test failure.
template <class F>
Error error_of(F&& f) {
    try {
        f();
    } catch (const Error& e) {
        return e;
    }
    ADD_FAILURE() << "expected an Error";
    return Error("none");
}

// Write a raw FITS image with cfitsio (shapes our writer refuses to make).
void write_raw(const std::string& path, int naxis, std::vector<long> naxes) {
    fitsfile* f = nullptr;
    int status = 0;
    fits_create_file(&f, ("!" + path).c_str(), &status);
    fits_create_img(f, FLOAT_IMG, naxis, naxes.data(), &status);
    long n = 1;
    for (long a : naxes) n *= a;
    std::vector<float> zeros(std::max(n, 1L), 0.0f);
    if (n > 0) fits_write_img(f, TFLOAT, 1, n, zeros.data(), &status);
    fits_close_file(f, &status);
    ASSERT_EQ(status, 0);
}

}  // namespace

TEST(FitsRead, HdfnImageAndHeader) {
    const std::string file = hdfn_dir() + "/hdfn_f814w_v2.fits";
    FitsReader fits(file);
    EXPECT_EQ(fits.place(), file);  // a primary HDU without EXTNAME is the file itself
    const ImageArray image = fits.read_image();
    EXPECT_EQ(image.rows(), 512);
    EXPECT_EQ(image.cols(), 512);
    EXPECT_TRUE(image.isFinite().all());
    EXPECT_EQ(fits.required_double("EXPTIME"), 123600.0);
    EXPECT_EQ(fits.required_string("CTYPE1"), "RA---TAN");
    EXPECT_EQ(fits.required_int("NAXIS1"), 512);
    EXPECT_FALSE(fits.optional_double("NOSUCHKEY"));
    const Error e = error_of([&] { fits.required_double("NOSUCHKEY"); });
    EXPECT_EQ(std::string(e.what()), file + ": NOSUCHKEY: keyword is missing");
    const Error type = error_of([&] { fits.required_double("CTYPE1"); });
    EXPECT_EQ(type.field(), "CTYPE1");  // cfitsio's own text for a non-numeric value
}

TEST(FitsRead, TinyTimPsfWithRawNewlineInAHeaderCard) {
    const std::string file = hdfn_dir() + "/wfpc2_f814w_tinytim_psf.fits";
    FitsReader fits(file);
    const ImageArray psf = fits.read_image();
    EXPECT_EQ(psf.rows(), 300);
    EXPECT_EQ(psf.cols(), 300);
    EXPECT_GT(psf.sum(), 0.0);
    EXPECT_EQ(fits.required_double("PIXSCALE"), 0.01);
    EXPECT_EQ(fits.required_string("CREATED").rfind("Thu Mar 28 14:35:54 2002", 0), 0u);
    EXPECT_EQ(fits.required_string("FILTER"), "F814W");
}

TEST(FitsRead, ReferenceStampsByExtnameAndExtendedSyntax) {
    const std::string file = test::reference_dir() + "/stamps.fits";
    FitsReader fits(file);
    const auto hdus = fits.list_hdus();
    ASSERT_EQ(hdus.size(), 25u);
    EXPECT_EQ(fits.hdu_index(), 0);  // listing keeps the current HDU
    EXPECT_TRUE(hdus[0].naxes.empty());
    EXPECT_EQ(hdus[1].extname, "M01");
    EXPECT_EQ(hdus[24].extname, "M24");
    EXPECT_TRUE(hdus[11].is_image);
    EXPECT_EQ(hdus[11].naxes, (std::vector<long long>{160, 121}));  // M11: nx × ny

    fits.move_to("M11");
    EXPECT_EQ(fits.place(), file + "[M11]");
    EXPECT_EQ(fits.hdu_index(), 11);
    const ImageArray m11 = fits.read_image();
    EXPECT_EQ(m11.cols(), 160);  // x along columns
    EXPECT_EQ(m11.rows(), 121);
    EXPECT_EQ(fits.required_double("NMAX"), 20);
    // The same pixels as the test suite's independent cfitsio reader.
    EXPECT_TRUE((m11 == test::read_fits_image(file, 12)).all());

    EXPECT_EQ(read_fits_image(file + "[M13]").cols(), 41);
    EXPECT_EQ(read_fits_image(file + "[M13]").rows(), 32);
    EXPECT_TRUE((read_fits_image(file + "[2]") == test::read_fits_image(file, 3)).all());
    // No HDU given: the first image, skipping the empty primary.
    EXPECT_TRUE((read_fits_image(file) == test::read_fits_image(file, 2)).all());
    FitsReader m02(file + "[2]");
    EXPECT_EQ(m02.place(), file + "[M02]");
    EXPECT_TRUE(fits.has_hdu("M24"));
    EXPECT_FALSE(fits.has_hdu("M99"));
    EXPECT_EQ(fits.hdu_index(), 11);
    EXPECT_EQ(std::string(error_of([&] { fits.move_to("M99"); }).what()),
              file + ": no HDU named 'M99'");
    EXPECT_EQ(error_of([&] { fits.move_to(30); }).file(), file + "[30]");
    EXPECT_EQ(error_of([&] { read_fits_image(file + "[M99]"); }).file(), file + "[M99]");
}

TEST_F(FitsTest, PixelConventionRowIsYColumnIsX) {
    const ImageArray image = index_image(3, 5);
    FitsWriter out(path("conv.fits"), "test");
    out.write_image(image, {"SCI", -64, "", {}, {}, {}});
    out.commit();
    // cfitsio's pixel (x, y) = (3, 2), 1-based, is image(j = 1, i = 2).
    fitsfile* f = nullptr;
    int status = 0, any_null = 0;
    long first[2] = {3, 2};
    double value = 0.0;
    fits_open_file(&f, (path("conv.fits") + "[SCI]").c_str(), READONLY, &status);
    fits_read_pix(f, TDOUBLE, first, 1, nullptr, &value, &any_null, &status);
    fits_close_file(f, &status);
    ASSERT_EQ(status, 0);
    EXPECT_EQ(value, image(1, 2));
    EXPECT_EQ(value, 1002.125);
}

// A window of the image (what a tiled detection reads) is exactly its block of the whole, and
// a window reaching beyond the image is refused, naming the file.
TEST_F(FitsTest, RegionIsItsBlockOfTheWholeImage) {
    const ImageArray image = index_image(9, 13);
    FitsWriter out(path("region.fits"), "test");
    out.write_image(image, {"SCI", -32, "", {}, {}, {}});
    out.commit();
    FitsReader fits(path("region.fits"), FitsStart::first_image);
    const ImageArray whole = fits.read_image();
    const ImageArray region = fits.read_region(4, 3, 6, 5);  // x 4–9, y 3–7
    ASSERT_EQ(region.rows(), 5);
    ASSERT_EQ(region.cols(), 6);
    EXPECT_TRUE((region == whole.block(2, 3, 5, 6)).all());
    EXPECT_TRUE((fits.read_region(1, 1, 13, 9) == whole).all());
    EXPECT_TRUE((fits.read_region(13, 9, 1, 1) == whole.block(8, 12, 1, 1)).all());
    for (const auto& [x0, y0, nx, ny] : {std::array<long, 4>{0, 1, 2, 2}, {1, 0, 2, 2},
                                         {12, 1, 3, 1}, {1, 9, 1, 2}, {1, 1, 0, 1}})
        EXPECT_EQ(error_of([&] { fits.read_region(x0, y0, nx, ny); }).file(),
                  path("region.fits") + "[SCI]")
            << x0 << " " << y0 << " " << nx << " " << ny;
}

TEST_F(FitsTest, MefRoundTripWithKeywordsWcsAndHistory) {
    const ImageArray a = index_image(7, 4);
    ImageArray b = index_image(3, 9) / 3.0;
    Wcs wcs = tan_wcs(189.2, 62.2, 0.03985, 128.5, 99.25, 12.0);
    FitsImageSpec sci{"SCI", -64, "DN/s", wcs, {}, {"rendered by a test"}};
    sci.keywords = {{"EXPTIME", 123600.0, "seconds"},
                    {"THIRD", 1.0 / 3.0},
                    {"NOBJ", 42},
                    {"BIGINT", 9007199254740993LL},
                    {"GOOD", true},
                    {"LONGSTR", std::string(150, 'x') + "end"},
                    {"A_VERY_LONG_NAME", 0.5}};
    const std::vector<FitsKeyword> primary = {{"SEED", 7}, {"OPT_LIKE", "hdf.fits"}};
    {
        FitsWriter out(path("mef.fits"), "shapesim-test", primary, {"history line"});
        out.write_image(a, sci);
        out.write_image(b, {"WEIGHT", -32, "", {}, {}, {}});
        EXPECT_FALSE(fs::exists(path("mef.fits")));  // nothing at the target until commit
        out.commit();
    }
    EXPECT_EQ(file_count(), 1u);
    FitsReader fits(path("mef.fits"));
    EXPECT_EQ(fits.required_string("PROGRAM"), "shapesim-test");
    EXPECT_EQ(fits.required_string("VERSION"), version());
    EXPECT_EQ(fits.required_string("CFITSIO").substr(0, 2), "4.");
    EXPECT_FALSE(fits.has_key("DATE"));  // a creation time would break bit-identical reruns
    EXPECT_EQ(fits.required_int("SEED"), 7);
    EXPECT_EQ(fits.required_string("OPT_LIKE"), "hdf.fits");
    EXPECT_EQ(fits.list_hdus().size(), 3u);

    fits.move_to("SCI");
    EXPECT_TRUE((fits.read_image() == a).all());  // −64: exact
    EXPECT_EQ(fits.required_string("BUNIT"), "DN/s");
    EXPECT_EQ(fits.required_double("EXPTIME"), 123600.0);
    EXPECT_EQ(fits.required_double("THIRD"), 1.0 / 3.0);  // doubles read back exactly
    EXPECT_EQ(fits.required_int("NOBJ"), 42);
    EXPECT_EQ(fits.required_int("BIGINT"), 9007199254740993LL);
    EXPECT_EQ(fits.required_string("LONGSTR"), std::string(150, 'x') + "end");
    EXPECT_EQ(fits.required_double("A_VERY_LONG_NAME"), 0.5);  // HIERARCH
    const Wcs back = read_wcs(fits);
    EXPECT_EQ(back.keywords().crpix1, wcs.keywords().crpix1);
    EXPECT_EQ(back.keywords().crval2, wcs.keywords().crval2);
    EXPECT_EQ(back.keywords().cd1_1, wcs.keywords().cd1_1);
    EXPECT_EQ(back.keywords().cd1_2, wcs.keywords().cd1_2);
    EXPECT_EQ(back.keywords().cd2_1, wcs.keywords().cd2_1);
    EXPECT_EQ(back.keywords().cd2_2, wcs.keywords().cd2_2);

    fits.move_to("WEIGHT");
    EXPECT_TRUE((fits.read_image() == b.cast<float>().cast<double>()).all());  // −32: float
    EXPECT_FALSE(has_wcs(fits));
}

TEST_F(FitsTest, NanPixelsReadAsNanAndBlankIntegersToo) {
    ImageArray image = index_image(4, 4);
    image(1, 2) = std::numeric_limits<double>::quiet_NaN();
    ImageArray counts = index_image(2, 3).floor();
    counts(0, 1) = -32768;
    {
        FitsWriter out(path("nan.fits"), "test");
        out.write_image(image, {"FLOAT32", -32, "", {}, {}, {}});
        out.write_image(image, {"FLOAT64", -64, "", {}, {}, {}});
        out.write_image(counts, {"COUNTS", 16, "", {}, {{"BLANK", -32768}}, {}});
        out.commit();
    }
    for (const char* hdu : {"FLOAT32", "FLOAT64"}) {
        const ImageArray back = read_fits_image(path("nan.fits") + "[" + hdu + "]");
        EXPECT_TRUE(std::isnan(back(1, 2))) << hdu;
        EXPECT_EQ(back.isNaN().count(), 1) << hdu;
    }
    const ImageArray back = read_fits_image(path("nan.fits[COUNTS]"));
    EXPECT_TRUE(std::isnan(back(0, 1)));
    EXPECT_EQ(back(1, 2), counts(1, 2));
}

// A float cannot hold the inverse variance of an image in physical units (σ ~ 1e−30: weights
// 1e60) nor values below its normal range: such an HDU asked for as −32 is written as −64 and
// reads back exactly; an ordinary image (and NaN, ±Inf, 0) stays −32.
// RADESYS passes through a WCS: read as the header gives it (ICRS when absent), written back,
// with EQUINOX 2000 for FK5.
TEST_F(FitsTest, RadesysRoundTrips) {
    WcsKeywords fk5_keywords = tan_wcs(189.2, 62.2, 0.04, 10.0, 10.0).keywords();
    fk5_keywords.radesys = "FK5";
    const Wcs fk5(fk5_keywords);
    {
        FitsWriter out(path("frames.fits"), "test");
        out.write_image(index_image(4, 4), {"FK5", -32, "", fk5, {}, {}});
        out.write_image(index_image(4, 4), {"ICRS", -32, "", tan_wcs(1.0, 2.0, 0.04, 1.0, 1.0), {}, {}});
        out.commit();
    }
    FitsReader in(path("frames.fits[FK5]"));
    EXPECT_EQ(read_wcs(in).keywords().radesys, "FK5");
    EXPECT_EQ(in.required_double("EQUINOX"), 2000.0);
    FitsReader icrs(path("frames.fits[ICRS]"));
    EXPECT_EQ(read_wcs(icrs).keywords().radesys, "ICRS");
    EXPECT_FALSE(icrs.has_key("EQUINOX"));
    FitsReader bare(shapesim::test::source_dir() + "/tests/corpus/cases/good.fits");  // no RADESYS card
    EXPECT_FALSE(bare.has_key("RADESYS"));
    EXPECT_EQ(read_wcs(bare).keywords().radesys, "ICRS");
}

// An image written row by row (begin_image, write_rows) is the image written whole, bytes and
// all; BITPIX −32 begun cannot be promoted, so a value beyond a float is refused; an image
// not finished cannot be committed, and rows past its end are refused.
TEST_F(FitsTest, RowsWrittenInOrderEqualTheWholeImage) {
    ImageArray image = index_image(7, 5) * 0.37;
    image(3, 2) = std::numeric_limits<double>::quiet_NaN();
    const FitsImageSpec spec{"SCI", -32, "", {}, {}, {}};
    {
        FitsWriter whole(path("whole.fits"), "test");
        whole.write_image(image, spec);
        whole.commit();
        FitsWriter rows(path("rows.fits"), "test");
        rows.begin_image(7, 5, spec);
        for (const auto& [first, count] : {std::pair{0, 3}, {3, 1}, {4, 3}})
            rows.write_rows(image.block(first, 0, count, 5));
        rows.commit();
    }
    std::ifstream a(path("whole.fits"), std::ios::binary), b(path("rows.fits"), std::ios::binary);
    const std::string bytes_a((std::istreambuf_iterator<char>(a)), {}),
        bytes_b((std::istreambuf_iterator<char>(b)), {});
    EXPECT_EQ(bytes_a, bytes_b);

    FitsWriter bad(path("bad.fits"), "test");
    bad.begin_image(2, 5, spec);
    ImageArray beyond = ImageArray::Constant(1, 5, 1.0);
    beyond(0, 4) = 1e40;
    EXPECT_THROW(bad.write_rows(beyond), FloatRangeError);
    bad.write_rows(ImageArray::Constant(1, 5, 1.0));
    EXPECT_THROW(bad.commit(), Error);  // one row of two written
    EXPECT_THROW(bad.write_rows(ImageArray::Constant(2, 5, 1.0)), Error);
    bad.write_rows(ImageArray::Constant(1, 5, 2.0));
    bad.commit();
    EXPECT_EQ(read_fits_image(path("bad.fits")).sum(), 15.0);
}

// BITPIX −32 pixels are written by our own conversion (float(v), big-endian, sixteen at a
// time and a tail one by one): cfitsio reads back exactly float(v) for every value a float
// holds — signed zeros, NaN, ±inf, the smallest normal and the largest float among them.
TEST_F(FitsTest, FloatPixelsAreTheirFloats) {
    const int ny = 70, nx = 61;  // 4270 pixels: a whole block of 4096 and a tail
    ImageArray image(ny, nx);
    RandomStream r(11, 3, "float pixels");
    for (Eigen::Index k = 0; k < image.size(); ++k)
        image.data()[k] = r.sign() * std::pow(10.0, r.uniform(-37.0, 38.0)) * r.uniform();
    const double specials[] = {0.0, -0.0, std::numeric_limits<double>::quiet_NaN(),
                               std::numeric_limits<double>::infinity(),
                               -std::numeric_limits<double>::infinity(),
                               double(std::numeric_limits<float>::min()),
                               double(std::numeric_limits<float>::max()), 1.0 + 0x1.0p-30, 1.0 / 3.0};
    for (std::size_t k = 0; k < std::size(specials); ++k) {
        image.data()[7 * k] = specials[k];            // in the vector block
        image.data()[4096 + 7 * k] = specials[k];     // in the tail
    }
    // Values below the smallest normal float would promote the HDU: none here.
    for (Eigen::Index k = 0; k < image.size(); ++k)
        if (std::abs(image.data()[k]) < std::numeric_limits<float>::min()) image.data()[k] = 0.0;
    {
        FitsWriter out(path("floats.fits"), "test");
        out.write_image(image, {"SCI", -32, "", {}, {}, {}});
        out.commit();
    }
    fitsfile* f = nullptr;
    int status = 0, any_null = 0, bitpix = 0;
    fits_open_file(&f, (path("floats.fits") + "[SCI]").c_str(), READONLY, &status);
    fits_get_img_type(f, &bitpix, &status);
    std::vector<float> back(std::size_t(image.size()));
    fits_read_img(f, TFLOAT, 1, LONGLONG(back.size()), nullptr, back.data(), &any_null, &status);
    fits_close_file(f, &status);
    ASSERT_EQ(status, 0);
    EXPECT_EQ(bitpix, FLOAT_IMG);
    for (Eigen::Index k = 0; k < image.size(); ++k) {
        const float expect = float(image.data()[k]);
        if (std::isnan(expect)) {
            EXPECT_TRUE(std::isnan(back[std::size_t(k)])) << k;
            continue;
        }
        std::uint32_t a, b;
        std::memcpy(&a, &expect, 4);
        std::memcpy(&b, &back[std::size_t(k)], 4);
        ASSERT_EQ(a, b) << "pixel " << k << " = " << image.data()[k];
    }
}

TEST_F(FitsTest, ValuesBeyondAFloatPromoteTheHduToDouble) {
    ImageArray ordinary = index_image(4, 3);
    ordinary(0, 0) = 0.0;
    ordinary(0, 1) = std::numeric_limits<double>::quiet_NaN();
    ordinary(0, 2) = -std::numeric_limits<double>::infinity();
    ImageArray weights = index_image(4, 3) * 1e60, tiny = index_image(4, 3) * 1e-40;
    EXPECT_TRUE(fits_in_float(ordinary));
    EXPECT_FALSE(fits_in_float(weights));
    EXPECT_FALSE(fits_in_float(tiny));
    // Tested in blocks of pixels: the last pixel of a large image counts too.
    ImageArray large = ImageArray::Constant(3, 5000, 1.0);
    large(2, 4999) = std::numeric_limits<double>::infinity();
    EXPECT_TRUE(fits_in_float(large));
    large(2, 4998) = -1e39;  // in the tail after the blocks
    EXPECT_FALSE(fits_in_float(large));
    large(2, 4998) = 1.0;
    large(1, 17) = -1e-39;  // inside a block: below the smallest normal float
    EXPECT_FALSE(fits_in_float(large));
    large(1, 17) = -0.0;
    large(0, 3) = std::numeric_limits<double>::quiet_NaN();
    EXPECT_TRUE(fits_in_float(large));
    {
        FitsWriter out(path("range.fits"), "test");
        out.write_image(ordinary, {"ORDINARY", -32, "", {}, {}, {}});
        out.write_image(weights, {"WEIGHTS", -32, "", {}, {}, {}});
        out.write_image(tiny, {"TINY", -32, "", {}, {}, {}});
        out.commit();
    }
    const std::vector<std::pair<const char*, long long>> expected = {
        {"ORDINARY", -32}, {"WEIGHTS", -64}, {"TINY", -64}};
    for (const auto& [hdu, bitpix] : expected) {
        FitsReader in(path("range.fits") + "[" + hdu + "]");
        EXPECT_EQ(in.required_int("BITPIX"), bitpix) << hdu;
    }
    const ImageArray back = read_fits_image(path("range.fits[WEIGHTS]"));
    EXPECT_EQ((back - weights).abs().maxCoeff(), 0.0);
    EXPECT_EQ((read_fits_image(path("range.fits[TINY]")) - tiny).abs().maxCoeff(), 0.0);
}

TEST_F(FitsTest, WriterLeavesNoFileWhenAnExceptionHappensMidWrite) {
    std::ofstream(path("keep.fits")) << "previous run";
    ImageArray big = index_image(4, 4);
    big(2, 2) = 1e10;  // does not fit BITPIX 16
    const auto fails = [&](auto&& write) {
        EXPECT_THROW(
            {
                FitsWriter out(path("keep.fits"), "test");
                out.write_image(index_image(2, 2), {"OK", -32, "", {}, {}, {}});
                write(out);
                out.commit();
            },
            Error);
        EXPECT_EQ(file_count(), 1u);  // no temporary left behind
        std::ifstream in(path("keep.fits"));
        std::string text;
        std::getline(in, text);
        EXPECT_EQ(text, "previous run");  // the old output is untouched
    };
    fails([&](FitsWriter& out) { out.write_image(big, {"I16", 16, "", {}, {}, {}}); });
    ImageArray nan = index_image(2, 2);
    nan(0, 0) = NAN;
    fails([&](FitsWriter& out) { out.write_image(nan, {"I8", 8, "", {}, {}, {}}); });
    fails([&](FitsWriter& out) { out.write_image(big, {"BAD", -16, "", {}, {}, {}}); });
    fails([&](FitsWriter& out) { out.write_image(ImageArray(0, 3), {"E", -32, "", {}, {}, {}}); });
    fails([&](FitsWriter& out) {
        out.write_image(big, {"K", -32, "", {}, {{"NANKEY", std::nan("")}}, {}});
    });
    fails([&](FitsWriter&) { throw Error("the caller fails between HDUs"); });
}

TEST_F(FitsTest, WriterRefusesUnwritableOrUnsupportedPaths) {
    EXPECT_EQ(error_of([&] { FitsWriter(path("no/such/dir.fits"), "t"); }).file(),
              path("no/such/dir.fits"));
    EXPECT_THROW(FitsWriter(dir_, "t"), Error);
    EXPECT_THROW(FitsWriter("-", "t"), Error);
    EXPECT_THROW(FitsWriter(path("a.fits.gz"), "t"), Error);
    EXPECT_THROW(FitsWriter(path("a.fits[1]"), "t"), Error);
    EXPECT_EQ(file_count(), 0u);
}

TEST_F(FitsTest, MissingFile) {
    const Error e = error_of([&] { read_fits_image(path("nope.fits")); });
    EXPECT_EQ(std::string(e.what()),
              path("nope.fits") + ": cannot open: No such file or directory");
    EXPECT_EQ(error_of([&] { read_fits_image(path("nope.fits") + "[SCI]"); }).file(),
              path("nope.fits") + "[SCI]");
}

TEST_F(FitsTest, NonFitsFile) {
    std::ofstream(path("text.fits")) << "This is not a FITS file, just some text.\n";
    const Error e = error_of([&] { read_fits_image(path("text.fits")); });
    EXPECT_EQ(e.file(), path("text.fits"));
    EXPECT_NE(e.message().find("not a FITS file"), std::string::npos) << e.what();
    // A longer text file fails on its first card instead.
    std::ofstream(path("long.txt")) << std::string(3000, 'x');
    EXPECT_NE(error_of([&] { FitsReader{path("long.txt")}; }).message().find("not a FITS file"),
              std::string::npos);
    EXPECT_EQ(error_of([&] { FitsReader{dir_}; }).message(), "cannot open: is a directory");
}

TEST_F(FitsTest, TruncatedFile) {
    {
        FitsWriter out(path("full.fits"), "test");
        out.write_image(index_image(100, 100), {"SCI", -64, "", {}, {}, {}});
        out.commit();
    }
    // Cut inside the data (headers are 2 × 2880 bytes, data 80 000 bytes), then inside the
    // extension's header.
    fs::copy_file(path("full.fits"), path("cut.fits"));
    fs::resize_file(path("cut.fits"), 2 * 2880 + 40000);
    Error e = error_of([&] { read_fits_image(path("cut.fits")); });
    EXPECT_EQ(e.file(), path("cut.fits") + "[SCI]");
    // Refused before the declared image is allocated, with the sizes.
    EXPECT_EQ(e.message(), "truncated: the header declares 80000 bytes of pixels, the file holds 40000");
    // Only the last block's padding missing: every pixel is there, and the image reads.
    fs::copy_file(path("full.fits"), path("unpadded.fits"));
    fs::resize_file(path("unpadded.fits"), 2 * 2880 + 80000);
    EXPECT_EQ((read_fits_image(path("unpadded.fits")) - index_image(100, 100)).abs().maxCoeff(), 0.0);
    fs::copy_file(path("full.fits"), path("cut2.fits"));
    fs::resize_file(path("cut2.fits"), 2880 + 1000);
    e = error_of([&] { read_fits_image(path("cut2.fits") + "[SCI]"); });
    EXPECT_EQ(e.file().rfind(path("cut2.fits"), 0), 0u) << e.what();
}

TEST_F(FitsTest, EmptyAndNon2dImages) {
    {
        FitsWriter out(path("empty.fits"), "test");  // only the empty primary HDU
        out.commit();
    }
    Error e = error_of([&] { read_fits_image(path("empty.fits")); });
    EXPECT_EQ(std::string(e.what()), path("empty.fits") + ": NAXIS: image is empty (NAXIS = 0)");

    write_raw(path("zero.fits"), 2, {0, 5});
    e = error_of([&] { read_fits_image(path("zero.fits")); });
    EXPECT_EQ(std::string(e.what()), path("zero.fits") + ": NAXIS1: image is empty");

    write_raw(path("cube.fits"), 3, {4, 5, 2});
    e = error_of([&] { read_fits_image(path("cube.fits")); });
    EXPECT_EQ(e.message(), "expected a 2D image, got NAXIS = 3 with NAXIS3 = 2");

    write_raw(path("line.fits"), 1, {7});
    EXPECT_EQ(error_of([&] { read_fits_image(path("line.fits")); }).field(), "NAXIS");

    write_raw(path("flat_cube.fits"), 3, {4, 5, 1});  // degenerate third axis: a 2D image
    const ImageArray flat = read_fits_image(path("flat_cube.fits"));
    EXPECT_EQ(flat.cols(), 4);
    EXPECT_EQ(flat.rows(), 5);
}

TEST_F(FitsTest, TableHduIsNotAnImage) {
    fitsfile* f = nullptr;
    int status = 0;
    char* names[] = {const_cast<char*>("FLUX")};
    char* forms[] = {const_cast<char*>("1D")};
    fits_create_file(&f, ("!" + path("table.fits")).c_str(), &status);
    fits_create_img(f, BYTE_IMG, 0, nullptr, &status);
    fits_create_tbl(f, BINARY_TBL, 0, 1, names, forms, nullptr, "CAT", &status);
    fits_close_file(f, &status);
    ASSERT_EQ(status, 0);
    FitsReader fits(path("table.fits[CAT]"));
    const Error e = error_of([&] { fits.read_image(); });
    EXPECT_EQ(std::string(e.what()), path("table.fits") + "[CAT]: not an image HDU (a table)");
    EXPECT_FALSE(fits.list_hdus()[1].is_image);
}

TEST_F(FitsTest, StampRoundTrip) {
    Stamp stamp;
    stamp.id = "17";
    stamp.image = index_image(6, 5);
    stamp.weight = ImageArray::Constant(6, 5, 2.5);
    stamp.mask = ImageArray::Zero(6, 5);
    stamp.mask(0, 4) = 1;
    stamp.x0 = 301;
    stamp.y0 = 12;
    Stamp other = stamp;
    other.id = "18";
    other.weight(2, 2) = 0.0;
    {
        FitsWriter out(path("stamps.fits"), "test");
        write_stamp(out, stamp);
        write_stamp(out, other);
        out.commit();
    }
    FitsReader fits(path("stamps.fits"));
    EXPECT_TRUE(fits.has_hdu(stamp_weight_extname("18")));
    for (const Stamp* s : {&other, &stamp}) {
        const Stamp back = read_stamp(fits, s->id);
        EXPECT_TRUE((back.image == s->image.cast<float>().cast<double>()).all());
        EXPECT_TRUE((back.weight == s->weight).all());
        EXPECT_TRUE((back.mask == s->mask).all());
        EXPECT_EQ(back.x0, 301);
        EXPECT_EQ(back.y0, 12);
    }
    EXPECT_EQ(stamp_image_extname("17"), "17.image");
    EXPECT_EQ(stamp_mask_extname("17"), "17.mask");
    // The names work in cfitsio's extended syntax too.
    EXPECT_TRUE((read_fits_image(path("stamps.fits[17.weight]")) == stamp.weight).all());
    EXPECT_TRUE(
        (read_fits_image(path("stamps.fits[18.image]")) == other.image.cast<float>().cast<double>())
            .all());
    EXPECT_EQ(std::string(error_of([&] { read_stamp(fits, "19"); }).what()),
              path("stamps.fits") + ": no HDU named '19.image'");
}

// A table whose layout cards hold a control or 8-bit byte is refused before cfitsio parses it
// (cfitsio overflowed a buffer on such a TTYPE, and asked calloc for 10^16 bytes on such a
// NAXIS2: the fuzz corpus keeps both files); a stray byte in another card is left alone.
TEST_F(FitsTest, LayoutCardsWithNonAsciiBytesAreRefusedBeforeCfitsio) {
    const std::string root = shapesim::test::source_dir() + "/tests/fuzz/corpus/fits/";
    // The third: a NAXIS1 the walk cannot parse ("0     880") before 8-bit TTYPE cards.
    // The fourth ends inside its table's header block: cfitsio reads the cards it holds.
    for (const char* name : {"cfitsio-calloc-naxis2-control-byte", "cfitsio-strcpy-ttype-8bit-byte",
                             "cfitsio-strcpy-ttype-after-unparsed-naxis1",
                             "cfitsio-strcpy-ttype-8bit-in-short-last-block"}) {
        try {
            FitsReader fits(root + name);
            ADD_FAILURE() << name << " opened";
        } catch (const Error& e) {
            EXPECT_NE(e.message().find("not printable ASCII"), std::string::npos) << e.message();
        }
    }
    // The shipped TinyTim PSF carries a newline in its CREATED card, and opens.
    EXPECT_NO_THROW(FitsReader(shapesim::test::source_dir() + "/share/data/hdfn/wfpc2_f814w_tinytim_psf.fits"));
}

// A column name, format or unit must be a quoted string: cfitsio copied an unquoted 70-character
// TTYPE into its 70-byte column name (a fortify abort, found twice by CI's fuzzing).
TEST_F(FitsTest, UnquotedTableLayoutTextIsRefusedBeforeCfitsio) {
    const std::string root = shapesim::test::source_dir() + "/tests/fuzz/corpus/fits/";
    for (const char* name : {"cfitsio-strcpy-unquoted-ttype", "cfitsio-strcpy-unquoted-ttype-2"}) {
        try {
            FitsReader fits(root + name);
            ADD_FAILURE() << name << " opened";
        } catch (const Error& e) {
            EXPECT_NE(e.message().find("(TTYPE"), std::string::npos) << e.message();
            EXPECT_NE(e.message().find("unquoted value"), std::string::npos) << e.message();
        }
    }
    // GalSim's own COSMOS catalogue table (the shipped layout) opens.
    EXPECT_NO_THROW(FitsReader(shapesim::test::source_dir() +
                               "/share/data/cosmos_catalog/real_galaxy_catalog_23.5_example.fits"));
}
