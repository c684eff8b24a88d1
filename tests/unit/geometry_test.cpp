// geometry: the TAN WCS against two independent routes (Calabretta & Greisen's native
// spherical coordinates, and cfitsio's AIPS-convention fits_pix_to_world), exact inversion,
// header reading (CD, PC/CDELT, CDELT/CROTA2) and `--like` on the real HDF-N image.
#include "shapesim/geometry.hpp"

#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"

#include <fitsio.h>
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>

using namespace shapesim;
namespace fs = std::filesystem;

namespace {
constexpr double deg = M_PI / 180.0;

std::string hdfn_dir() {
    if (const char* env = std::getenv("SHAPESIM_DATA"))
        if (fs::is_directory(std::string(env) + "/hdfn")) return std::string(env) + "/hdfn";
    return fs::path(__FILE__).parent_path().parent_path().parent_path() / "share/data/hdfn";
}

// Calabretta & Greisen (2002): intermediate → native (φ, θ) (eqs. 14, 54) → celestial (eq. 2)
// with (α_p, δ_p) = CRVAL and φ_p = 180°. A different route from the library's closed form.
SkyPosition native_route(const Wcs& wcs, double x, double y) {
    const WcsKeywords& w = wcs.keywords();
    const double dx = x - w.crpix1, dy = y - w.crpix2;
    const double xi = w.cd1_1 * dx + w.cd1_2 * dy, eta = w.cd2_1 * dx + w.cd2_2 * dy;  // deg
    const double r = std::hypot(xi, eta);
    const double phi = std::atan2(xi, -eta);
    const double theta = std::atan2(1.0, r * deg);  // tan θ = (180/π) / R_θ
    const double dp = w.crval2 * deg, dphi = phi - M_PI;
    const double ra = w.crval1 + std::atan2(-std::cos(theta) * std::sin(dphi),
                                            std::sin(theta) * std::cos(dp) -
                                                std::cos(theta) * std::sin(dp) * std::cos(dphi)) /
                                     deg;
    // δ by atan2, not asin: asin loses digits near the poles.
    const double sin_dec =
        std::sin(theta) * std::sin(dp) + std::cos(theta) * std::cos(dp) * std::cos(dphi);
    const double cos_dec = std::hypot(
        std::cos(theta) * std::sin(dphi),
        std::sin(theta) * std::cos(dp) - std::cos(theta) * std::sin(dp) * std::cos(dphi));
    const double dec = std::atan2(sin_dec, cos_dec);
    return {std::fmod(ra + 720.0, 360.0), dec / deg};
}

// Angular distance between two sky positions, arcsec.
double separation_arcsec(SkyPosition a, SkyPosition b) {
    const double c = std::sin(a.dec * deg) * std::sin(b.dec * deg) +
                     std::cos(a.dec * deg) * std::cos(b.dec * deg) * std::cos((a.ra - b.ra) * deg);
    const double s = std::hypot(
        std::cos(b.dec * deg) * std::sin((a.ra - b.ra) * deg),
        std::cos(a.dec * deg) * std::sin(b.dec * deg) -
            std::sin(a.dec * deg) * std::cos(b.dec * deg) * std::cos((a.ra - b.ra) * deg));
    return std::atan2(s, c) / deg * 3600.0;
}

class GeometryTest : public ::testing::Test {
protected:
    void SetUp() override {
        char pattern[] = "/tmp/shapesim-geometry-XXXXXX";
        ASSERT_NE(mkdtemp(pattern), nullptr);
        dir_ = pattern;
    }
    void TearDown() override { fs::remove_all(dir_); }
    // A 4×4 image whose header holds `keywords` and nothing else of the WCS.
    std::string image_with(const std::vector<FitsKeyword>& keywords) {
        const std::string path = dir_ + "/wcs.fits";
        FitsWriter out(path, "test");
        out.write_image(ImageArray::Zero(4, 4), {"SCI", -32, "", {}, keywords, {}});
        out.commit();
        return path;
    }
    std::string dir_;
};
}  // namespace

TEST(Wcs, ReferencePixelMapsToReferencePoint) {
    const Wcs w = tan_wcs(189.2, 62.2, 0.04, 256.5, 256.5, 30.0);
    const SkyPosition s = w.pixel_to_sky(256.5, 256.5);
    EXPECT_EQ(s.ra, 189.2);
    EXPECT_NEAR(s.dec, 62.2, 1e-13);  // degrees → radians → degrees: an ulp or two
    const PixelPosition p = w.sky_to_pixel(189.2, 62.2);
    EXPECT_EQ(p.x, 256.5);
    EXPECT_EQ(p.y, 256.5);
    EXPECT_NEAR(w.pixel_scale_arcsec(), 0.04, 1e-17);
}

TEST(Wcs, MatchesTheNativeSphericalRoute) {
    // Over a large field and far out (up to 30° off-axis), at several declinations, with
    // rotation and skew: agreement to 1e-9 arcsec (double rounding of a few ulp).
    for (double dec0 : {-89.5, -45.0, 0.0, 62.2036751382, 89.9}) {
        WcsKeywords skewed = tan_wcs(189.18661365727, dec0, 0.03985, 89.903, -24.759, 23.5).keywords();
        skewed.cd1_2 *= 1.01;  // a little skew, as in the HDF header
        const Wcs w(skewed);
        for (double x : {-1e6, -500.0, 1.0, 300.25, 2e5})
            for (double y : {-7e5, 0.5, 512.0, 9e5}) {
                const SkyPosition a = w.pixel_to_sky(x, y), b = native_route(w, x, y);
                EXPECT_LT(separation_arcsec(a, b), 1e-9) << dec0 << " " << x << " " << y;
                EXPECT_GE(a.ra, 0.0);
                EXPECT_LT(a.ra, 360.0);
            }
    }
}

TEST(Wcs, MatchesCfitsioWorldCoordinates) {
    // cfitsio's fits_pix_to_world (AIPS TAN with CDELT and CROTA2): an independent code path.
    const double scale = 0.03985, rotation = -17.25;
    const Wcs w = tan_wcs(10.5, -33.25, scale, 100.0, 200.0, rotation);
    for (double x : {-3000.0, 1.0, 100.0, 777.7})
        for (double y : {-1000.0, 50.5, 4000.0}) {
            double ra = 0, dec = 0;
            int status = 0;
            fits_pix_to_world(x, y, 10.5, -33.25, 100.0, 200.0, -scale / 3600, scale / 3600,
                              rotation, const_cast<char*>("-TAN"), &ra, &dec, &status);
            ASSERT_EQ(status, 0);
            EXPECT_LT(separation_arcsec(w.pixel_to_sky(x, y), {ra, dec}), 1e-8);
        }
}

TEST(Wcs, SkyToPixelInvertsPixelToSky) {
    WcsKeywords skewed = tan_wcs(359.999, 62.2, 0.03985, 89.903, -24.759, 41.0).keywords();
    skewed.cd2_1 *= 0.99;  // RA wraps through 0
    const Wcs w(skewed);
    for (double x : {-2e4, -100.0, 1.0, 256.5, 512.0, 3e4})
        for (double y : {-2e4, 1.0, 333.3, 3e4}) {
            const SkyPosition s = w.pixel_to_sky(x, y);
            const PixelPosition p = w.sky_to_pixel(s.ra, s.dec);
            EXPECT_NEAR(p.x, x, 1e-8 * (1 + std::abs(x)));
            EXPECT_NEAR(p.y, y, 1e-8 * (1 + std::abs(y)));
        }
}

TEST(Wcs, GnomonicClosedForms) {
    // On the equator with a 1″ pixel, a pixel offset of u along −x is ξ = u″ and the RA
    // offset is atan(ξ) exactly; along +y, δ = atan(η).
    const Wcs w = tan_wcs(100.0, 0.0, 1.0, 0.0, 0.0);
    const double u = 36000.0;  // 10 degrees of ξ
    EXPECT_NEAR(w.pixel_to_sky(-u, 0).ra, 100.0 + std::atan(10 * deg) / deg, 1e-12);
    EXPECT_NEAR(w.pixel_to_sky(0, u).dec, std::atan(10 * deg) / deg, 1e-12);
    EXPECT_NEAR(w.pixel_to_sky(0, u).ra, 100.0, 1e-12);
}

TEST(Wcs, FarSideAndInvalidWcsAreErrors) {
    const Wcs w = tan_wcs(0.0, 0.0, 1.0, 0.0, 0.0);
    EXPECT_THROW(w.sky_to_pixel(90.5, 0.0), Error);  // beyond the projection's horizon
    EXPECT_THROW(w.sky_to_pixel(180.0, 10.0), Error);
    EXPECT_NO_THROW(w.sky_to_pixel(89.0, 0.0));
    WcsKeywords bad = w.keywords();
    bad.cd1_1 = bad.cd1_2 = 0.0;
    EXPECT_THROW(Wcs{bad}, Error);
    bad = w.keywords();
    bad.ctype1 = "RA---TAN-SIP";
    try {
        Wcs{bad};
        FAIL() << "expected Error";
    } catch (const Error& e) {
        EXPECT_EQ(e.field(), "CTYPE1");
    }
    EXPECT_THROW(tan_wcs(0, 0, 0.0, 1, 1), Error);
}

TEST(FieldGeometry, LikeTheHdfnImage) {
    const std::string file = hdfn_dir() + "/hdfn_f814w_v2.fits";
    const FieldGeometry g = read_field_geometry(file);
    EXPECT_EQ(g.nx, 512);
    EXPECT_EQ(g.ny, 512);
    // The header's CD matrix: √|det CD| = 0.03985″ (data README).
    EXPECT_NEAR(g.pixel_scale, 0.03985, 5e-6);
    EXPECT_EQ(g.wcs.keywords().crpix1, 89.9030000000002);
    EXPECT_EQ(g.wcs.keywords().crval2, 62.2036751382);
    EXPECT_EQ(g.wcs.keywords().cd2_1, -4.466669e-6);
    EXPECT_NEAR(g.area_arcmin2(), 512.0 * 512 * g.pixel_scale * g.pixel_scale / 3600, 1e-12);
    // Pixel (1, 1) and (512, 512) are the diagonal of the field.
    const double diagonal =
        separation_arcsec(g.wcs.pixel_to_sky(1, 1), g.wcs.pixel_to_sky(512, 512));
    EXPECT_NEAR(diagonal, std::sqrt(2.0) * 511 * g.pixel_scale, 1e-3);
    EXPECT_THROW(read_field_geometry("/nonexistent/like.fits"), Error);
}

TEST_F(GeometryTest, HeaderConventionsAgree) {
    const Wcs ref = tan_wcs(150.0, 2.2, 0.05, 10.5, 20.5, 33.0);
    const double cdelt1 = -0.05 / 3600, cdelt2 = 0.05 / 3600;
    const std::vector<FitsKeyword> common = {{"CTYPE1", "RA---TAN"}, {"CTYPE2", "DEC--TAN"},
                                             {"CRPIX1", 10.5},       {"CRPIX2", 20.5},
                                             {"CRVAL1", 150.0},      {"CRVAL2", 2.2}};
    auto with = [&](std::vector<FitsKeyword> extra) {
        extra.insert(extra.begin(), common.begin(), common.end());
        FitsReader fits(image_with(extra), FitsStart::first_image);
        return read_wcs(fits);
    };
    const double r = 33.0 * deg;
    const Wcs crota = with({{"CDELT1", cdelt1}, {"CDELT2", cdelt2}, {"CROTA2", 33.0}});
    const Wcs pc = with({{"CDELT1", cdelt1},
                         {"CDELT2", cdelt2},
                         {"PC1_1", std::cos(r)},
                         {"PC1_2", -std::sin(r) * cdelt2 / cdelt1},
                         {"PC2_1", std::sin(r) * cdelt1 / cdelt2},
                         {"PC2_2", std::cos(r)}});
    for (const Wcs& w : {crota, pc}) {
        EXPECT_NEAR(w.keywords().cd1_1, ref.keywords().cd1_1, 1e-20);
        EXPECT_NEAR(w.keywords().cd1_2, ref.keywords().cd1_2, 1e-20);
        EXPECT_NEAR(w.keywords().cd2_1, ref.keywords().cd2_1, 1e-20);
        EXPECT_NEAR(w.keywords().cd2_2, ref.keywords().cd2_2, 1e-20);
    }
    try {
        with({{"CDELT1", cdelt1}});  // no CDELT2, no CD
        FAIL() << "expected Error";
    } catch (const Error& e) {
        EXPECT_EQ(std::string(e.what()), dir_ + "/wcs.fits[SCI]: CDELT2: keyword is missing");
    }
    try {
        with({{"CD1_1", cdelt1}, {"CD2_2", cdelt2}, {"CTYPE1", "RA---XYZ"}, {"CTYPE2", "DEC--XYZ"}});
        FAIL() << "expected Error";
    } catch (const Error& e) {  // a projection wcslib does not know
        EXPECT_EQ(e.field(), "CTYPE1");
        EXPECT_NE(std::string(e.what()).find("wcslib"), std::string::npos) << e.what();
    }
    FitsReader none(image_with({}), FitsStart::first_image);
    EXPECT_FALSE(has_wcs(none));
    EXPECT_EQ(std::string([&] {
                  try {
                      read_wcs(none);
                  } catch (const Error& e) {
                      return std::string(e.what());
                  }
                  return std::string("no error");
              }()),
              dir_ + "/wcs.fits[SCI]: CTYPE1: keyword is missing");
}

// SIP distortion (the corpus's sip.fits: TAN with A_0_2, A_2_0, B_1_1, up to 0.05 pixel at
// the corners): pixel → sky equals astropy 5.2's all_pix2world (origin 1) on the same header to
// 1e−12°, sky → pixel (wcslib's iterative inverse) inverts it to 1e−8 pixel, and the terms
// survive a write and a re-read.
TEST_F(GeometryTest, SipDistortionMatchesAstropyAndInverts) {
    FitsReader fits(shapesim::test::source_dir() + "/tests/corpus/cases/sip.fits", FitsStart::first_image);
    const Wcs w = read_wcs(fits);
    ASSERT_TRUE(w.keywords().has_sip());
    EXPECT_EQ(w.keywords().sip_order, 2);
    EXPECT_EQ(w.keywords().sip_a[0][2], 2e-5);
    EXPECT_EQ(w.keywords().sip_b[1][1], 1e-5);
    struct Reference {
        double x, y, ra, dec;
    };
    for (const Reference& r : {Reference{91.12839393884606, 30.96733893712243, 189.19936533540357,
                                         62.19962731421346},
                               Reference{1, 1, 189.2015122969175, 62.19929488423822},
                               Reference{128, 128, 189.19848667177973, 62.2007059953383},
                               Reference{1, 128, 189.20151236751698, 62.2007050992932}}) {
        const SkyPosition s = w.pixel_to_sky(r.x, r.y);
        EXPECT_NEAR(s.ra, r.ra, 1e-12) << r.x << " " << r.y;
        EXPECT_NEAR(s.dec, r.dec, 1e-12) << r.x << " " << r.y;
    }
    WcsKeywords undistorted = w.keywords();  // the distortion moves the corner: 0.045 pixel, 1.8 mas
    undistorted.sip_order = 0;
    undistorted.sip_a.clear();
    undistorted.sip_b.clear();
    undistorted.ctype1 = "RA---TAN";
    undistorted.ctype2 = "DEC--TAN";
    const Wcs plain(undistorted);
    EXPECT_GT(separation_arcsec(w.pixel_to_sky(1, 1), plain.pixel_to_sky(1, 1)), 0.0015);
    for (double x = -50; x <= 180; x += 23)
        for (double y = -50; y <= 180; y += 29) {
            const SkyPosition s = w.pixel_to_sky(x, y);
            const PixelPosition p = w.sky_to_pixel(s.ra, s.dec);
            EXPECT_NEAR(p.x, x, 1e-8);
            EXPECT_NEAR(p.y, y, 1e-8);
        }
    const std::string path = dir_ + "/sip_out.fits";
    {
        FitsWriter out(path, "test");
        out.write_image(ImageArray::Zero(4, 4), {"SCI", -32, "", w, {}, {}});
        out.commit();
    }
    FitsReader back_file(path, FitsStart::first_image);
    const Wcs back = read_wcs(back_file);
    EXPECT_EQ(back.keywords().ctype1, "RA---TAN-SIP");
    EXPECT_EQ(back.keywords().sip_a, w.keywords().sip_a);
    EXPECT_EQ(back.keywords().sip_b, w.keywords().sip_b);
}

// A -SIP CTYPE without its orders names the missing keyword; axes other than RA, Dec and two
// CTYPEs of different projections are refused naming the CTYPE.
TEST_F(GeometryTest, SipWithoutOrdersAndNonCelestialAxesAreRefused) {
    const std::vector<FitsKeyword> common = {{"CRPIX1", 10.5}, {"CRPIX2", 20.5},
                                             {"CRVAL1", 150.0}, {"CRVAL2", 2.2},
                                             {"CD1_1", -1e-5},  {"CD2_2", 1e-5}};
    auto error_with = [&](std::vector<FitsKeyword> extra) -> std::string {
        extra.insert(extra.end(), common.begin(), common.end());
        try {
            FitsReader fits(image_with(extra), FitsStart::first_image);
            read_wcs(fits);
        } catch (const Error& e) {
            return e.what();
        }
        return "no error";
    };
    EXPECT_NE(error_with({{"CTYPE1", "RA---TAN-SIP"}, {"CTYPE2", "DEC--TAN-SIP"}}).find("A_ORDER"),
              std::string::npos);
    EXPECT_NE(error_with({{"CTYPE1", "GLON-TAN"}, {"CTYPE2", "GLAT-TAN"}})
                  .find("CTYPE1: expected RA--- and a projection code (e.g. RA---TAN; RA first), got "
                        "'GLON-TAN'"),
              std::string::npos);
    EXPECT_NE(error_with({{"CTYPE1", "RA---TAN"}, {"CTYPE2", "DEC--SIN"}})
                  .find("CTYPE2: expected DEC--TAN (the projection of CTYPE1), got 'DEC--SIN'"),
              std::string::npos);
}

// Survey projections through wcslib (tests/data/wcs/make.py writes the headers and the
// references): a DECam-like TPV (TAN with third-order distortion in PVi_m) and VISTA VIRCAM's
// ZPN (PV2_1, PV2_3, PV2_5). pixel → sky equals astropy's all_pix2world (origin 1) to 1e−10°
// (a FITS pixel here is 0.26–0.34″ = 7e−5–9e−5°), including 5000 pixels outside the image;
// sky → pixel inverts it; the keywords survive a write and a re-read, and a cutout sees the
// same sky at its own pixels.
TEST_F(GeometryTest, TpvAndZpnMatchAstropy) {
    struct Reference {
        const char* file;
        double x, y, ra, dec;
    };
    const Reference references[] = {
        {"tpv", 1, 1, 52.72830196060297, -28.087234486206327},
        {"tpv", 64, 64, 52.72298242293244, -28.08265871482098},
        {"tpv", 32.25, 17.5, 52.72567260979004, -28.086047883104076},
        {"tpv", -3000, 5000, 52.975892106105626, -27.71650186016857},
        {"tpv", 1024.5, 2048.5, 52.641514890140044, -27.93729999276812},
        {"zpn", 1, 1, 150.68199671606337, 2.340407115338793},
        {"zpn", 64, 64, 150.67614559500353, 2.3463235847309263},
        {"zpn", 32.25, 17.5, 150.67909390682985, 2.341962114305446},
        {"zpn", -3000, 5000, 150.9570175563803, 2.8023808308381475},
        {"zpn", 6037.5, -1500.5, 150.1163, 2.200899999995613}};
    for (const Reference& r : references) {
        const std::string file = shapesim::test::source_dir() + "/tests/data/wcs/" + r.file + ".fits";
        FitsReader fits(file, FitsStart::first_image);
        const Wcs w = read_wcs(fits);
        EXPECT_EQ(w.keywords().projection(), std::string(r.file) == "tpv" ? "TPV" : "ZPN");
        const SkyPosition s = w.pixel_to_sky(r.x, r.y);
        EXPECT_NEAR(s.ra, r.ra, 1e-10) << r.file << " " << r.x << " " << r.y;
        EXPECT_NEAR(s.dec, r.dec, 1e-10) << r.file << " " << r.x << " " << r.y;
        const PixelPosition p = w.sky_to_pixel(r.ra, r.dec);
        EXPECT_NEAR(p.x, r.x, 1e-6) << r.file;
        EXPECT_NEAR(p.y, r.y, 1e-6) << r.file;

        const std::string path = dir_ + "/" + r.file + "_out.fits";
        {
            FitsWriter out(path, "test");
            out.write_image(ImageArray::Zero(4, 4), {"SCI", -32, "", w.cutout(11, 21), {}, {}});
            out.commit();
        }
        FitsReader back_file(path, FitsStart::first_image);
        const Wcs back = read_wcs(back_file);
        EXPECT_EQ(back.keywords().pv, w.keywords().pv);
        const SkyPosition t = back.pixel_to_sky(r.x - 10, r.y - 20);
        EXPECT_NEAR(t.ra, r.ra, 1e-10) << r.file;
        EXPECT_NEAR(t.dec, r.dec, 1e-10) << r.file;
    }
}

TEST(Wcs, CutoutSeesTheSameSkyAtItsOwnPixels) {
    // A cutout whose first pixel is the field's (x0, y0): its pixel (x − x0 + 1, y − y0 + 1)
    // is the field's (x, y) on the sky, with and without SIP distortion (its terms are in
    // offsets from CRPIX). Shifts are whole pixels; agreement is to the 1e-8 px of wcslib's
    // iterative inverse of the distortion.
    const Wcs field = tan_wcs(189.2, 62.2, 0.04, 256.5, 256.5, 30.0);
    WcsKeywords sip = field.keywords();
    sip.ctype1 = "RA---TAN-SIP";
    sip.ctype2 = "DEC--TAN-SIP";
    sip.sip_order = 2;
    sip.sip_a = {{0.0, 0.0, 2e-6}, {0.0, -1e-6, 0.0}, {3e-6, 0.0, 0.0}};
    sip.sip_b = {{0.0, 0.0, -2e-6}, {0.0, 4e-6, 0.0}, {1e-6, 0.0, 0.0}};
    for (const Wcs& w : {field, Wcs(sip)}) {
        const long x0 = 301, y0 = 17;
        const Wcs cut = w.cutout(x0, y0);
        EXPECT_EQ(cut.keywords().crpix1, w.keywords().crpix1 - 300.0);
        EXPECT_EQ(cut.keywords().crpix2, w.keywords().crpix2 - 16.0);
        EXPECT_EQ(cut.keywords().sip_a, w.keywords().sip_a);
        for (const auto& [x, y] : {std::pair{301.0, 17.0}, {400.25, 90.5}, {1000.0, -40.0}}) {
            const SkyPosition a = w.pixel_to_sky(x, y);
            const PixelPosition p = cut.sky_to_pixel(a.ra, a.dec);
            EXPECT_NEAR(p.x, x - double(x0 - 1), 1e-8);
            EXPECT_NEAR(p.y, y - double(y0 - 1), 1e-8);
        }
        // Its own first pixel: a cutout from (1, 1) is the WCS itself.
        const Wcs same = w.cutout(1, 1);
        EXPECT_EQ(same.keywords().crpix1, w.keywords().crpix1);
        EXPECT_EQ(same.keywords().crpix2, w.keywords().crpix2);
    }
}

// A tiled detection's windows: the cores partition the image (tile_grid), each window is its
// core grown by the margin on every side and clipped to the image.
TEST(TileWindows, CoresPartitionWindowsPadThemWithinTheImage) {
    const std::vector<TileWindow> tiles = tile_windows(1000, 700, 384, 64);
    ASSERT_EQ(tiles.size(), 6u);
    std::vector<int> covered(1000 * 700, 0);
    for (const TileWindow& t : tiles) {
        for (long y = t.core.y0; y <= t.core.y1; ++y)
            for (long x = t.core.x0; x <= t.core.x1; ++x)
                ++covered[std::size_t((y - 1) * 1000 + (x - 1))];
        EXPECT_EQ(t.window.x0, std::max(t.core.x0 - 64, 1L));
        EXPECT_EQ(t.window.y0, std::max(t.core.y0 - 64, 1L));
        EXPECT_EQ(t.window.x1, std::min(t.core.x1 + 64, 1000L));
        EXPECT_EQ(t.window.y1, std::min(t.core.y1 + 64, 700L));
    }
    EXPECT_TRUE(std::all_of(covered.begin(), covered.end(), [](int c) { return c == 1; }));
    EXPECT_EQ(tiles[4].window.x0, 385 - 64);
    EXPECT_EQ(tiles[4].window.x1, 768 + 64);
    EXPECT_EQ(tiles[4].window.y1, 700);
    EXPECT_EQ(tile_windows(1000, 700, 2000, 64).size(), 1u);
    EXPECT_THROW(tile_windows(10, 10, 4, -1), Error);
    EXPECT_THROW(tile_windows(10, 10, 0, 2), Error);
}
