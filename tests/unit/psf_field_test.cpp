// A PSF varying across the field (psf_field.hpp): PSFEx's file as psfex writes it, and its
// shapelet form, against exact references — a field built from known shapelet PSFs (the fit
// must give them back) and psfex's own model of a ground-based star field (tests/data/psfex).
#include "shapesim/psf_field.hpp"

#include "shapesim/basis1d.hpp"
#include "shapesim/error.hpp"
#include "shapesim/moments.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

using namespace shapesim;

namespace {

// The samples of a Cartesian model (centre 0) as PSFEx holds them: each a box one image pixel
// wide about the sample, samples `step` pixels apart, the centre on sample (w/2, h/2).
ImageArray effective_samples(const CartesianModel& c, int w, int h, double step) {
    ImageArray out = ImageArray::Zero(h, w);
    std::vector<double> ix(std::size_t(c.n_max + 1)), iy(std::size_t(c.n_max + 1));
    for (int row = 0; row < h; ++row)
        for (int col = 0; col < w; ++col) {
            const double x = (col - w / 2) * step, y = (row - h / 2) * step;
            hermite_integrals((x - 0.5) / c.beta_pix, (x + 0.5) / c.beta_pix, c.n_max, ix.data());
            hermite_integrals((y - 0.5) / c.beta_pix, (y + 0.5) / c.beta_pix, c.n_max, iy.data());
            double v = 0.0;
            for (int n1 = 0; n1 <= c.n_max; ++n1)
                for (int n2 = 0; n1 + n2 <= c.n_max; ++n2)
                    v += c.b(n1, n2) * ix[std::size_t(n1)] * iy[std::size_t(n2)];
            out(row, col) = c.beta_pix * v;
        }
    return out;
}

// A degree-1 field of three known PSFs: round, and stretched along x and along y.
PsfexModel known_field(double step, const std::vector<CartesianModel>& parts) {
    PsfexModel m;
    m.variation.degree = 1;
    m.variation.x_zero = 500;
    m.variation.y_zero = 400;
    m.variation.x_scale = 900;
    m.variation.y_scale = 800;
    m.sampling = step;
    m.x_name = "X_IMAGE";
    m.y_name = "Y_IMAGE";
    const int w = int(std::lround(31 / step)) | 1;
    for (const CartesianModel& c : parts) m.components.push_back(effective_samples(c, w, w, step));
    return m;
}

std::vector<CartesianModel> known_parts() {
    const double beta = 2.2;
    const int n = 6;
    CartesianModel a(0, 0, beta, n), bx(0, 0, beta, n), by(0, 0, beta, n);
    a.b(0, 0) = 1.0;
    a.b(2, 0) = 0.15;
    a.b(0, 2) = 0.15;
    a.b(4, 0) = -0.03;
    bx.b(2, 0) = 0.08;
    bx.b(1, 1) = 0.02;
    by.b(0, 2) = 0.06;
    by.b(3, 1) = -0.01;
    return {a, bx, by};
}

}  // namespace

TEST(PsfField, KnownShapeletPsfsAreFittedBackAtEveryPlace) {
    for (double step : {1.0, 0.5}) {
        const std::vector<CartesianModel> parts = known_parts();
        const PsfexModel m = known_field(step, parts);
        PsfFieldOptions o;
        o.residual_target = 1e-9;
        o.n_max_min = 6;
        o.n_max_cap = 6;
        o.beta_tolerance = 1e-7;
        const PsfField f = fit_psf_field(m, o);
        EXPECT_EQ(f.n_max, 6);
        EXPECT_NEAR(f.beta_pix, 2.2, 1e-5) << "step " << step;
        EXPECT_LT(f.max_residual_fraction, 1e-8) << "step " << step;
        for (double x : {10.0, 500.0, 940.0})
            for (double y : {5.0, 400.0, 790.0}) {
                const std::vector<double> t = m.variation.terms(x, y);
                CartesianModel truth(0, 0, 2.2, 6);
                for (std::size_t k = 0; k < 3; ++k) truth.b += t[k] * parts[k].b;
                truth.b /= moments(truth).flux;
                const CartesianModel got = f.at(x, y);
                EXPECT_NEAR(moments(got).flux, 1.0, 1e-12);
                EXPECT_LT((got.b - truth.b).cwiseAbs().maxCoeff(), 1e-5)
                    << "step " << step << " at " << x << ", " << y;
            }
    }
}

TEST(PsfField, TermsAreInPsfexOrder) {
    PsfexModel m;
    m.variation.degree = 2;
    m.variation.x_zero = 10;
    m.variation.y_zero = 20;
    m.variation.x_scale = 2;
    m.variation.y_scale = 4;
    const std::vector<double> t = m.variation.terms(14, 32);  // x̃ = 2, ỹ = 3
    const std::vector<double> want = {1, 2, 4, 3, 6, 9};
    ASSERT_EQ(t.size(), want.size());
    for (std::size_t k = 0; k < t.size(); ++k) EXPECT_DOUBLE_EQ(t[k], want[k]) << k;
}

TEST(PsfField, PsfexModelOfAGroundFieldIsReadAndFitted) {
    const std::string file = shapesim::test::source_dir() + "/tests/data/psfex/ground.psf";
    const PsfexModel m = read_psfex(file);
    EXPECT_EQ(m.variation.degree, 2);
    EXPECT_EQ(m.components.size(), 6u);
    EXPECT_EQ(m.components[0].cols(), 25);
    EXPECT_DOUBLE_EQ(m.sampling, 1.0);
    EXPECT_EQ(m.x_name, "X_IMAGE");
    const PsfField f = fit_psf_field(m);
    EXPECT_TRUE(f.reached_target) << f.max_residual_fraction;
    // The shapelet PSF's size and shape follow PSFEx's across the field (the stars' PSF grows
    // with y; e1 grows with x): the second moments of its pixel image against PSFEx's image.
    auto shape = [](const ImageArray& im) {
        double s = 0, sx = 0, sy = 0;
        for (long r = 0; r < im.rows(); ++r)
            for (long c = 0; c < im.cols(); ++c) {
                s += im(r, c);
                sx += c * im(r, c);
                sy += r * im(r, c);
            }
        const double cx = sx / s, cy = sy / s;
        double xx = 0, yy = 0, xy = 0;
        for (long r = 0; r < im.rows(); ++r)
            for (long c = 0; c < im.cols(); ++c) {
                const double w = im(r, c) * std::exp(-((c - cx) * (c - cx) + (r - cy) * (r - cy)) / 18.0);
                xx += w * (c - cx) * (c - cx);
                yy += w * (r - cy) * (r - cy);
                xy += w * (c - cx) * (r - cy);
            }
        return std::array<double, 3>{xx + yy, (xx - yy) / (xx + yy), 2 * xy / (xx + yy)};
    };
    for (double x : {60.0, 512.0, 980.0})
        for (double y : {60.0, 512.0, 980.0}) {
            const ImageArray want = psfex_image(m, x, y);
            PsfexModel one = m;
            one.variation.degree = 0;
            one.components = {effective_samples(f.at(x, y), 25, 25, 1.0)};
            const ImageArray got = one.components[0] * want.sum() / one.components[0].sum();
            const auto a = shape(want), b = shape(got);
            EXPECT_NEAR(b[0] / a[0], 1.0, 0.005) << x << ", " << y;
            EXPECT_NEAR(b[1], a[1], 0.002) << x << ", " << y;
            EXPECT_NEAR(b[2], a[2], 0.002) << x << ", " << y;
            EXPECT_LT((got - want).abs().maxCoeff() / want.maxCoeff(), 0.01) << x << ", " << y;
        }
}

TEST(PsfField, WhatIsNotAPsfexModelIsRefusedNamingTheFile) {
    const std::string image = shapesim::test::source_dir() + "/tests/data/statmorph/slice.fits";
    try {
        read_psfex(image);
        FAIL() << "an image was read as a PSFEx model";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("slice.fits"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("PSF_DATA"), std::string::npos) << e.what();
    }
}

TEST(PsfField, SamplesOutOfRangeAreAnErrorNotACrash) {
    PsfexModel m = known_field(1.0, known_parts());
    m.components[0] *= 1e300;  // finite, but their squares are not
    EXPECT_THROW(fit_psf_field(m), Error);
    m = known_field(1.0, known_parts());
    m.components[0].setZero();  // no light at all
    EXPECT_THROW(fit_psf_field(m), Error);
}
