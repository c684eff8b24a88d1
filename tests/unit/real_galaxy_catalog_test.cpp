// real_galaxy_catalog.hpp: GalSim's RealGalaxyCatalog read (the shipped AEGIS table; columns,
// defaults, folders, integer and text identifiers; errors placed at the table, row and
// column; a table declaring more rows than its file holds), and catalogues written here in
// that layout, with the real COSMOS ACS PSFs shipped in share/data/cosmos_catalog, fitted
// through their own PSFs back to the intrinsic galaxies they were made from.
#include "shapesim/real_galaxy_catalog.hpp"

#include "shapesim/convolve.hpp"
#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/polar.hpp"
#include "shapesim/render.hpp"
#include "test_support.hpp"

#include <fitsio.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <filesystem>
#include <string>
#include <vector>

using namespace shapesim;
namespace fs = std::filesystem;

namespace {

// share/data of this repository, or $SHAPESIM_DATA.
std::string data_dir() {
    if (const char* env = std::getenv("SHAPESIM_DATA")) return env;
    return fs::absolute(fs::path(__FILE__).parent_path().parent_path().parent_path() /
                        "share/data")
        .lexically_normal()
        .string();
}

// One row as GalSim writes it.
struct Row {
    long long ident = 0;
    double mag = 24.0;
    std::string gal_file;
    long long gal_hdu = 0;
    std::string psf_file;
    long long psf_hdu = 0;
    double pixel_scale = 0.03, noise_mean = 0.0, noise_variance = 1e-4, weight = 1.0;
};

// A RealGalaxyCatalog table (HDU 1) with GalSim's column types; `drop` leaves one column out,
// `text_ident` writes IDENT as text.
void write_catalogue(const std::string& path, const std::vector<Row>& rows,
                     const std::string& drop = {}, bool text_ident = false) {
    std::vector<std::string> names = {"IDENT",        "RA",      "DEC",         "MAG",
                                      "BAND",         "WEIGHT",  "GAL_FILENAME", "PSF_FILENAME",
                                      "GAL_HDU",      "PSF_HDU", "PIXEL_SCALE", "NOISE_MEAN",
                                      "NOISE_VARIANCE"};
    std::vector<std::string> forms = {text_ident ? "12A" : "K", "D", "D", "D", "5A", "D",
                                      "256A", "256A", "K", "K", "D", "D", "D"};
    std::vector<char*> ttype, tform;
    for (std::size_t k = 0; k < names.size(); ++k)
        if (names[k] != drop) {
            ttype.push_back(names[k].data());
            tform.push_back(forms[k].data());
        }
    int status = 0;
    fitsfile* f = nullptr;
    const std::string create = "!" + path;
    fits_create_file(&f, create.c_str(), &status);
    fits_create_tbl(f, BINARY_TBL, 0, int(ttype.size()), ttype.data(), tform.data(), nullptr,
                    "", &status);
    for (std::size_t r = 0; r < rows.size(); ++r) {
        const Row& row = rows[r];
        const LONGLONG at = LONGLONG(r) + 1;
        int column = 0;
        for (const std::string& name : names) {
            if (name == drop) continue;
            ++column;
            double d = 0.0;
            long long k = 0;
            std::string text;
            if (name == "IDENT" && text_ident) text = "g" + std::to_string(row.ident);
            else if (name == "IDENT") k = row.ident;
            else if (name == "RA") d = 150.1 + 1e-4 * double(r);
            else if (name == "DEC") d = 2.2;
            else if (name == "MAG") d = row.mag;
            else if (name == "BAND") text = "F814W";
            else if (name == "WEIGHT") d = row.weight;
            else if (name == "GAL_FILENAME") text = row.gal_file;
            else if (name == "PSF_FILENAME") text = row.psf_file;
            else if (name == "GAL_HDU") k = row.gal_hdu;
            else if (name == "PSF_HDU") k = row.psf_hdu;
            else if (name == "PIXEL_SCALE") d = row.pixel_scale;
            else if (name == "NOISE_MEAN") d = row.noise_mean;
            else if (name == "NOISE_VARIANCE") d = row.noise_variance;
            if (name == "BAND" || name == "GAL_FILENAME" || name == "PSF_FILENAME" ||
                (name == "IDENT" && text_ident)) {
                char* cell = text.data();
                fits_write_col(f, TSTRING, column, at, 1, 1, &cell, &status);
            } else if (name == "IDENT" || name == "GAL_HDU" || name == "PSF_HDU") {
                fits_write_col(f, TLONGLONG, column, at, 1, 1, &k, &status);
            } else {
                fits_write_col(f, TDOUBLE, column, at, 1, 1, &d, &status);
            }
        }
    }
    fits_close_file(f, &status);
    ASSERT_EQ(status, 0) << "cfitsio status " << status;
}

class RealGalaxyCatalogTest : public ::testing::Test {
protected:
    void SetUp() override {
        char pattern[] = "/tmp/shapesim-rgc-XXXXXX";
        ASSERT_NE(mkdtemp(pattern), nullptr);
        dir_ = pattern;
    }
    void TearDown() override { fs::remove_all(dir_); }
    std::string dir_;
};

TEST_F(RealGalaxyCatalogTest, ReadsTheShippedAegisCatalogue) {
    const std::string folder = data_dir() + "/cosmos_aegis";
    const auto rows = read_real_galaxy_catalog(folder + "/AEGIS_F814w_catalog.fits");
    ASSERT_EQ(rows.size(), 5u);
    EXPECT_EQ(rows[0].ident, "23409");
    EXPECT_EQ(rows[0].row, 1);
    EXPECT_DOUBLE_EQ(rows[0].mag, 24.7407);
    EXPECT_EQ(rows[0].band, "F814W");
    EXPECT_EQ(rows[0].image, folder + "/AEGIS_F814w_images_01.fits[0]");
    EXPECT_EQ(rows[0].psf, folder + "/AEGIS_F814w_PSF_images_01.fits[0]");
    EXPECT_DOUBLE_EQ(rows[0].pixel_scale, 0.03);
    EXPECT_NEAR(rows[0].noise_variance, 7.01618908e-06, 1e-14);
    EXPECT_NEAR(*rows[0].ra, 215.2103071, 1e-9);
    EXPECT_EQ(rows[1].image, folder + "/AEGIS_F814w_images_01.fits[1]");
    EXPECT_EQ(rows[4].ident, "24216");
    // Another folder for the files: the names are kept, the folder replaced.
    const auto moved =
        read_real_galaxy_catalog(folder + "/AEGIS_F814w_catalog.fits", "/elsewhere");
    EXPECT_EQ(moved[0].image, "/elsewhere/AEGIS_F814w_images_01.fits[0]");
}

// Galaxies made from known intrinsic models through real COSMOS PSFs (HDUs 0, 37 and 99 of the
// shipped PSF file), written as a RealGalaxyCatalog, read and fitted back: each model's flux
// within 3σ of its error and 1%, its rms radius within 3%, its centre within 0.1 pixel. The
// third stamp holds a neighbour 20 pixels away (blended at the detection isophote), which the
// job masks: the fit's bias a quarter of the unmasked fit's or less.
TEST_F(RealGalaxyCatalogTest, FitsGalaxiesThroughTheirOwnRealPsfs) {
    const std::string psfs = data_dir() + "/cosmos_catalog/real_galaxy_PSF_images.fits";
    const int side = 61;
    const double sigma = 0.002;
    const std::vector<int> psf_hdus = {0, 37, 99};
    std::vector<Row> rows;
    std::vector<ShapeletModel> truths;
    FitsWriter images(dir_ + "/images.fits", "test");
    for (std::size_t k = 0; k < psf_hdus.size(); ++k) {
        Row row;
        row.ident = 1000 + long(k);
        row.gal_file = "images.fits";
        row.gal_hdu = long(k) + 1;  // HDU 0 is FitsWriter's header-only primary
        row.psf_file = psfs;
        row.psf_hdu = psf_hdus[k];
        row.noise_variance = sigma * sigma;
        row.noise_mean = 0.01;
        RealGalaxy g;
        g.psf = psfs + "[" + std::to_string(psf_hdus[k]) + "]";
        g.pixel_scale = row.pixel_scale;
        const PsfModel psf = real_galaxy_psf(read_real_galaxy_psf(g, "test"), g.pixel_scale, 41);
        const ShapeletModel truth = test::centred_galaxy(4, 3.0 + double(k), side, 7 + k, 20.0);
        ImageArray stamp = test::noisy_stamp(convolve(truth, psf.model), side, sigma, 11, k);
        if (k == 2) {  // a compact neighbour, through the same PSF
            ShapeletModel other = test::centred_galaxy(2, 1.5, side, 99, 8.0);
            other.x += 20.0;
            other.y += 3.0;
            stamp += render_stamp(convolve(other, psf.model), side, side);
        }
        images.write_image(stamp + row.noise_mean, {});
        rows.push_back(row);
        truths.push_back(truth);
    }
    images.commit();
    write_catalogue(dir_ + "/catalogue.fits", rows);

    const auto galaxies = read_real_galaxy_catalog(dir_ + "/catalogue.fits");
    ASSERT_EQ(galaxies.size(), 3u);
    for (std::size_t k = 0; k < galaxies.size(); ++k) {
        SCOPED_TRACE("galaxy " + std::to_string(k));
        const RealGalaxy& g = galaxies[k];
        EXPECT_EQ(g.image, dir_ + "/images.fits[" + std::to_string(k + 1) + "]");
        DecomposeJob job = real_galaxy_job(g, "catalogue.fits");
        EXPECT_EQ(job.source.extra["neighbours_masked"], k == 2 ? 1 : 0);
        EXPECT_EQ(job.stamp.mask.sum() > 0.0, k == 2);
        EXPECT_EQ(job.source.extra["image"], "catalogue.fits");
        const PsfModel psf = real_galaxy_psf(read_real_galaxy_psf(g, "catalogue.fits"),
                                             g.pixel_scale, 41);
        job.psf = to_cartesian(psf.model);
        const DecomposeOutcome o = decompose_job(job, DecomposeOptions{}, {});
        ASSERT_TRUE(o.record) << o.error;
        EXPECT_EQ(o.record->extra["frame"], "intrinsic");
        const ShapeletModel fit = o.record->to_model();
        const Moments want = moments(truths[k]), got = moments(fit);
        if (k < 2) {
            const double flux_error = o.record->extra["flux_err"].get<double>();
            EXPECT_NEAR(got.flux, want.flux, 3.0 * flux_error);
            EXPECT_NEAR(got.flux / want.flux, 1.0, 0.01);
            EXPECT_NEAR(got.rms_radius / want.rms_radius, 1.0, 0.03);
            EXPECT_NEAR(got.x, want.x, 0.1);
            EXPECT_NEAR(got.y, want.y, 0.1);
        } else {
            // The neighbour's wings below its segment's isophote still reach the fit (as in a
            // field's stamps: cut_stamp masks alike): +6% in flux, +9% in size, 1 pixel
            // towards it; unmasked, +40%, +39% and 5.7 pixels.
            DecomposeJob bare = job;
            bare.stamp.mask.setZero();
            const DecomposeOutcome b = decompose_job(bare, DecomposeOptions{}, {});
            ASSERT_TRUE(b.record) << b.error;
            const Moments unmasked = moments(b.record->to_model());
            EXPECT_NEAR(got.flux / want.flux, 1.0, 0.08);
            EXPECT_NEAR(got.rms_radius / want.rms_radius, 1.0, 0.12);
            EXPECT_LT(std::abs(got.flux / want.flux - 1.0),
                      0.25 * std::abs(unmasked.flux / want.flux - 1.0));
            EXPECT_LT(std::abs(got.x - want.x), 0.25 * std::abs(unmasked.x - want.x));
        }
    }
}

TEST_F(RealGalaxyCatalogTest, TextIdentifiersAndDefaultsOfOptionalColumns) {
    Row row;
    row.ident = 5;
    row.gal_file = "a.fits";
    row.psf_file = "b.fits";
    write_catalogue(dir_ + "/text.fits", {row}, {}, true);
    EXPECT_EQ(read_real_galaxy_catalog(dir_ + "/text.fits")[0].ident, "g5");
    write_catalogue(dir_ + "/noweight.fits", {row}, "WEIGHT");
    const auto g = read_real_galaxy_catalog(dir_ + "/noweight.fits");
    EXPECT_EQ(g[0].weight, 1.0);
    EXPECT_EQ(g[0].image, dir_ + "/a.fits[0]");
    write_catalogue(dir_ + "/nomean.fits", {row}, "NOISE_MEAN");
    EXPECT_EQ(read_real_galaxy_catalog(dir_ + "/nomean.fits")[0].noise_mean, 0.0);
}

// Every refusal names the table, the row (as the line) and the column.
TEST_F(RealGalaxyCatalogTest, ErrorsNameTheRowAndColumn) {
    Row good;
    good.ident = 1;
    good.gal_file = "a.fits";
    good.psf_file = "b.fits";
    const auto error_of = [&](const std::vector<Row>& rows, const std::string& drop = {}) {
        write_catalogue(dir_ + "/bad.fits", rows, drop);
        try {
            read_real_galaxy_catalog(dir_ + "/bad.fits");
        } catch (const Error& e) {
            return e;
        }
        return Error("no error");
    };
    Error e = error_of({good}, "NOISE_VARIANCE");
    EXPECT_EQ(e.field(), "NOISE_VARIANCE");
    EXPECT_NE(e.message().find("no column"), std::string::npos) << e.message();
    Row bad = good;
    bad.pixel_scale = 0.0;
    e = error_of({good, bad});
    EXPECT_EQ(e.line(), 2);
    EXPECT_EQ(e.field(), "PIXEL_SCALE");
    EXPECT_EQ(e.file(), dir_ + "/bad.fits[1]");
    bad = good;
    bad.gal_hdu = -1;
    EXPECT_EQ(error_of({bad}).field(), "GAL_HDU");
    bad = good;
    bad.noise_variance = -1.0;
    EXPECT_EQ(error_of({good, good, bad}).line(), 3);
    bad = good;
    bad.weight = -0.5;
    EXPECT_EQ(error_of({bad}).field(), "WEIGHT");
    bad = good;
    bad.psf_file = "";
    EXPECT_EQ(error_of({bad}).field(), "PSF_FILENAME");
    bad = good;
    bad.mag = std::nan("");
    EXPECT_EQ(error_of({bad}).field(), "MAG");
    // A stamp that is not there: the job's error names the catalogue's row and column.
    write_catalogue(dir_ + "/missing.fits", {good, good});
    const auto rows = read_real_galaxy_catalog(dir_ + "/missing.fits");
    try {
        real_galaxy_job(rows[1], "missing.fits");
        FAIL() << "no error for a missing stamp";
    } catch (const Error& missing) {
        EXPECT_EQ(missing.file(), "missing.fits");
        EXPECT_EQ(missing.line(), 2);
        EXPECT_EQ(missing.field(), "GAL_FILENAME");
        EXPECT_NE(missing.message().find("a.fits"), std::string::npos) << missing.message();
    }
    // Not a table at all: an image file.
    FitsWriter image(dir_ + "/image.fits", "test");
    image.write_image(ImageArray::Zero(4, 4), {});
    image.commit();
    EXPECT_THROW(read_real_galaxy_catalog(dir_ + "/image.fits"), Error);
}

// A header declaring a billion rows in a file of a few: refused before anything is allocated.
TEST_F(RealGalaxyCatalogTest, RowsBeyondTheFileAreRefused) {
    Row good;
    good.ident = 1;
    good.gal_file = "a.fits";
    good.psf_file = "b.fits";
    const std::string path = dir_ + "/big.fits";
    write_catalogue(path, {good, good});
    // The table's NAXIS2 card rewritten in the file's bytes (cfitsio would write the rows).
    std::string bytes;
    {
        std::ifstream in(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    const auto at = bytes.find("NAXIS2  =");
    ASSERT_NE(at, std::string::npos);
    char card[81];
    std::snprintf(card, sizeof card, "%-8s= %20ld", "NAXIS2", 1000000000L);
    bytes.replace(at, 30, std::string(card).substr(0, 30));
    {
        std::ofstream out(path, std::ios::binary | std::ios::trunc);
        out << bytes;
    }
    try {
        read_real_galaxy_catalog(path);
        FAIL() << "no error";
    } catch (const Error& e) {
        EXPECT_NE(e.message().find("truncated"), std::string::npos) << e.message();
    }
}

}  // namespace
