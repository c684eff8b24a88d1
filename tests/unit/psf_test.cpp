// Pixel resampling (resample.hpp) and PSF mode (psf.hpp): exact identities where there are
// any (flux conservation, box variance, aligned resampling, recovery of a known shapelet PSF),
// the derived sampling error where there is one, and the shipped TinyTim WFPC2 F814W PSF at
// the HDF pixel scale against the acceptance criterion (max |residual| < 1% of the peak).
//
// Sampling error of resampling a piecewise-constant fine image (fine pixel h coarse pixels):
// the fine pixels give the cumulative flux G exactly at fine pixel edges and linearly in
// between, so a coarse pixel edge at fraction t of a fine pixel carries the linear
// interpolation error G_lin − G = (h² t(1−t)/2)·f' (f = G'). A coarse pixel [a, b] whose
// two edges have the same phase (integer ratio) is off by (h² t(1−t)/2)(f'(b) − f'(a)) ≈
// (h² t(1−t)/2)·∂²P/∂x², P the exact pixel-integrated image as a function of position: to
// leading order a Gaussian blur of variance h² t(1−t) per axis. So a pixel-integrated
// Gaussian of σ resampled at phase t equals the exact pixel-integrated Gaussian of
// σ'² = σ² + h² t(1−t) up to O(h⁴), and differs from that of σ by ≈ h² t(1−t)/2 · |∇²P|.
#include "shapesim/psf.hpp"

#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/render.hpp"
#include "shapesim/resample.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <iostream>
#include <random>
#include <string>
#include <vector>

using namespace shapesim;

namespace {

constexpr double pi = 3.14159265358979323846;

void report(const std::string& name, double value) {
    std::cout << "  [measured] " << name << " = " << value << "\n";
    ::testing::Test::RecordProperty(name, std::to_string(value));
}

// A pixel-integrated circular Gaussian of unit flux and σ (pixels) centred at (x, y).
ImageArray gaussian_stamp(double sigma, double x, double y, int nx, int ny) {
    ShapeletModel g(x, y, sigma, 0);
    g.at(0, 0) = Complex(1.0 / (2.0 * std::sqrt(pi) * sigma), 0.0);  // F = 2√π β a_00
    return render_stamp(g, nx, ny);
}

// The discrete box kernel's variance (resample.hpp box_convolve).
double box_variance(double w) {
    const double a = 0.5 * w;
    const double k = std::floor(a - 0.5), r = a - k - 0.5;
    return (2.0 / w) * (k * (k + 1) * (2 * k + 1) / 6.0 + r * (k + 1) * (k + 1));
}

struct PixelMoments {
    double flux = 0, x = 0, y = 0, xx = 0, yy = 0;
};
PixelMoments pixel_moments(const ImageArray& a) {
    PixelMoments m;
    for (int j = 0; j < a.rows(); ++j)
        for (int i = 0; i < a.cols(); ++i) {
            m.flux += a(j, i);
            m.x += a(j, i) * (i + 1);
            m.y += a(j, i) * (j + 1);
        }
    m.x /= m.flux;
    m.y /= m.flux;
    for (int j = 0; j < a.rows(); ++j)
        for (int i = 0; i < a.cols(); ++i) {
            m.xx += a(j, i) * std::pow(i + 1 - m.x, 2);
            m.yy += a(j, i) * std::pow(j + 1 - m.y, 2);
        }
    m.xx /= m.flux;
    m.yy /= m.flux;
    return m;
}

std::string tinytim_path() {
    return shapesim::test::source_dir() + "/share/data/hdfn/wfpc2_f814w_tinytim_psf.fits";
}

}  // namespace

// =============================================================================================
// Resampling

TEST(Resample, FluxIsConservedWhenTheFineImageLiesInside) {
    std::mt19937_64 engine(7);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    ImageArray fine(29, 37);
    for (Eigen::Index k = 0; k < fine.size(); ++k) fine.data()[k] = u(engine);
    const double total = fine.sum();
    // Non-integer ratios, arbitrary placements, and an output finer than the input.
    for (double coarse : {0.037, 0.04, 0.1, 0.0071}) {
        const double ratio = coarse / 0.01;
        const int n = int(std::ceil(80.0 / ratio)) + 4;  // covers the fine image with margin
        const PixelPosition out_point{0.5 * (n + 1) + 0.21, 0.5 * (n + 1) - 0.4};
        const ImageArray out =
            resample_pixel_integrated(fine, 0.01, coarse, {15.3, 19.7}, n, n, out_point);
        EXPECT_NEAR(out.sum(), total, 1e-12 * total) << coarse;
        EXPECT_GE(out.minCoeff(), 0.0);
    }
    // Partly outside: only the covered part is kept.
    const ImageArray part =
        resample_pixel_integrated(fine, 0.01, 0.04, {1.0, 1.0}, 5, 5, {1.0, 1.0});
    EXPECT_LT(part.sum(), 0.5 * total);
    EXPECT_THROW(resample_pixel_integrated(fine, 0.0, 0.04, {1, 1}, 5, 5, {1, 1}), Error);
    EXPECT_THROW(resample_pixel_integrated(fine, 0.01, 0.04, {1, 1}, 0, 5, {1, 1}), Error);
    EXPECT_THROW(resample_pixel_integrated(ImageArray(), 0.01, 0.04, {1, 1}, 5, 5, {1, 1}), Error);
}

// A fine pixel-integrated Gaussian resampled 4:1 equals the exact pixel-integrated Gaussian to
// rounding when the coarse edges fall on fine edges, and to the derived sampling error (file
// comment) when they fall at phase t: ≈ h²t(1−t)/2·|∇²P| from the Gaussian of σ, and the
// blur is matched by the Gaussian of σ'² = σ² + h²t(1−t) up to O(h⁴).
TEST(Resample, GaussianEqualsTheExactPixelIntegratedGaussian) {
    const int ratio = 4, n = 32;
    const double sigma = 1.5, h = 1.0 / ratio;
    const PixelPosition coarse_centre{16.3, 15.8};
    // Fine FITS u ↔ coarse FITS x with the edges aligned: u = 4x − 1.5.
    const PixelPosition fine_centre{ratio * coarse_centre.x - 1.5, ratio * coarse_centre.y - 1.5};
    const ImageArray fine =
        gaussian_stamp(ratio * sigma, fine_centre.x, fine_centre.y, ratio * n, ratio * n);
    for (double t : {0.0, 0.1, 0.25, 0.5}) {
        // Shifting the fine reference point by t fine pixels puts the coarse edges at phase t
        // and the Gaussian at coarse_centre − t·h.
        const ImageArray out = resample_pixel_integrated(
            fine, 1.0, double(ratio), {fine_centre.x + t, fine_centre.y + t}, n, n, coarse_centre);
        const double x = coarse_centre.x - t * h, y = coarse_centre.y - t * h;
        const ImageArray exact = gaussian_stamp(sigma, x, y, n, n);
        const double peak = exact.maxCoeff();
        const double error = (out - exact).abs().maxCoeff() / peak;
        // |∇²P| ≤ 2P/σ² at the peak for a Gaussian: the bound h²t(1−t)/σ² (relative to peak).
        const double predicted = h * h * t * (1 - t) / (sigma * sigma);
        const ImageArray blurred =
            gaussian_stamp(std::sqrt(sigma * sigma + h * h * t * (1 - t)), x, y, n, n);
        const double blurred_error = (out - blurred).abs().maxCoeff() / peak;
        report("resample_error_phase_" + std::to_string(t), error);
        report("resample_error_vs_blurred_phase_" + std::to_string(t), blurred_error);
        if (t == 0.0) {
            EXPECT_LT(error, 1e-13);
        } else {
            EXPECT_LT(error, 1.1 * predicted) << t;
            EXPECT_GT(error, 0.5 * predicted) << t;   // the derived error is the actual one
            EXPECT_LT(blurred_error, 0.05 * error) << t;  // and it is the stated blur
        }
    }
}

// box_convolve is a discrete convolution with the kernel k_p = |[p−½, p+½] ∩ [−w/2, w/2]|/w:
// flux and centroid are kept exactly and the variance adds exactly V(w) (resample.hpp).
TEST(Resample, BoxVarianceAddsExactlyAsDerived) {
    EXPECT_NEAR(box_variance(3.0), 8.0 / 12.0, 1e-15);
    EXPECT_NEAR(box_variance(2.0), 6.0 / 12.0, 1e-15);
    EXPECT_NEAR(box_variance(1.0), 0.0, 1e-15);
    ImageArray image(33, 41);
    for (int j = 0; j < 33; ++j)
        for (int i = 0; i < 41; ++i)
            image(j, i) =
                std::exp(-0.5 * (std::pow(i - 19.3, 2) / 9.0 + std::pow(j - 15.8, 2) / 4.0)) +
                0.3 * std::exp(-0.5 * (std::pow(i - 25.0, 2) + std::pow(j - 20.0, 2)));
    const PixelMoments m0 = pixel_moments(image);
    for (double w : {0.5, 1.0, 1.82, 2.0, 2.5, 3.0, 4.0, 4.98, 9.96, 10.0}) {
        const ImageArray out = box_convolve(image, w);
        const int pad = int(std::ceil(0.5 * w));
        ASSERT_EQ(out.rows(), image.rows() + 2 * pad);
        const PixelMoments m = pixel_moments(out);
        EXPECT_NEAR(m.flux, m0.flux, 1e-12 * m0.flux) << w;
        EXPECT_NEAR(m.x - pad, m0.x, 1e-11) << w;
        EXPECT_NEAR(m.y - pad, m0.y, 1e-11) << w;
        EXPECT_NEAR(m.xx - m0.xx, box_variance(w), 1e-10) << w;
        EXPECT_NEAR(m.yy - m0.yy, box_variance(w), 1e-10) << w;
        EXPECT_GE(box_variance(w), (w * w - 1.0) / 12.0 - 1e-12) << w;
        EXPECT_LT(box_variance(w), w * w / 12.0 + 0.175) << w;
    }
    EXPECT_THROW(box_convolve(image, 0.0), Error);
    EXPECT_THROW(box_convolve(image, std::nan("")), Error);
}

TEST(Resample, FluxCentroidIsInFitsCoordinates) {
    ImageArray image = ImageArray::Zero(5, 7);
    image(0, 0) = 1.0;  // FITS (1, 1)
    image(4, 6) = 3.0;  // FITS (7, 5)
    const PixelPosition c = flux_centroid(image);
    EXPECT_DOUBLE_EQ(c.x, (1.0 + 3.0 * 7.0) / 4.0);
    EXPECT_DOUBLE_EQ(c.y, (1.0 + 3.0 * 5.0) / 4.0);
    EXPECT_THROW(flux_centroid(ImageArray::Zero(3, 3)), Error);
    EXPECT_THROW(flux_centroid(ImageArray()), Error);
}

// =============================================================================================
// PSF mode

// A Gaussian PSF 4× oversampled: the piecewise-constant blur keeps it a Gaussian (variance
// + h²t(1−t) per axis, equal phases here up to the centroid's position), so n_max stays small.
TEST(Psf, OversampledGaussianNeedsFewOrders) {
    const int fine_side = 161, ratio = 4;
    const double sigma = 1.6;  // coarse pixels
    const ImageArray fine = gaussian_stamp(ratio * sigma, 80.37, 81.12, fine_side, fine_side);
    PsfFitOptions options;
    options.residual_target = 1e-3;
    const PsfModel psf = psf_from_oversampled(fine, 0.01, 0.04, {}, 31, options);
    report("gaussian_psf_n_max", psf.n_max);
    report("gaussian_psf_beta_pix", psf.model.beta_pix);
    report("gaussian_psf_max_residual_fraction", psf.max_residual_fraction);
    report("gaussian_psf_rms_residual_fraction", psf.rms_residual_fraction);
    report("gaussian_psf_flux_outside_stamp", psf.flux_outside_stamp);
    EXPECT_TRUE(psf.reached_target);
    EXPECT_LE(psf.n_max, 2);
    EXPECT_LT(psf.max_residual_fraction, 1e-3);
    EXPECT_NEAR(flux(psf.model), 1.0, 1e-12);
    // β is σ blurred by at most h²/4 (h = 1/4 pixel).
    EXPECT_GE(psf.model.beta_pix, sigma * (1 - 1e-3));
    EXPECT_LE(psf.model.beta_pix, std::sqrt(sigma * sigma + 1.0 / 64.0) * (1 + 1e-3));
    // The centre pixel holds the centroid.
    const Moments m = moments(psf.model);
    EXPECT_NEAR(m.x, 16.0, 1e-3);
    EXPECT_NEAR(m.y, 16.0, 1e-3);
    EXPECT_LT(psf.flux_outside_stamp, 1e-12);
    // The image and residual are scaled with the model.
    EXPECT_NEAR(psf.image.sum(), 1.0, 1e-6);
    EXPECT_NEAR(psf.residual.abs().maxCoeff() / psf.peak, psf.max_residual_fraction, 1e-12);
}

// A known shapelet PSF (n_max 6, centroid on its basis centre, unit flux), rendered 4×
// finer and resampled with aligned edges (exact, see above), is recovered: n_max 6, β, centre
// and coefficients to 1e-6 of the largest coefficient.
TEST(Psf, RecoversAKnownShapeletPsf) {
    const int ratio = 4, n = 31, n_max = 6;
    const double beta = 2.1;
    const PixelPosition centre{16.27, 15.64};
    ShapeletModel truth = test::random_model(n_max, beta, centre.x, centre.y, 2024u);
    // Put the centroid on the basis centre: Σ_{n odd} √(n+1) a_{n,1} = 0.
    Complex sum(0.0, 0.0);
    for (int k = 3; k <= n_max; k += 2) sum += std::sqrt(k + 1.0) * truth.at(k, 1);
    truth.at(1, 1) = -sum / std::sqrt(2.0);
    const double f = flux(truth);
    for (Complex& a : truth.coeffs) a /= f;
    ASSERT_NEAR(moments(truth).dx, 0.0, 1e-14);
    ASSERT_NEAR(moments(truth).dy, 0.0, 1e-14);

    // The same function at 4× finer pixels: β·4, coefficients /4 (flux per pixel is kept).
    ShapeletModel fine_model = truth;
    fine_model.beta_pix = ratio * beta;
    fine_model.x = ratio * centre.x - 1.5;
    fine_model.y = ratio * centre.y - 1.5;
    for (Complex& a : fine_model.coeffs) a /= double(ratio);
    const ImageArray fine = render_stamp(fine_model, ratio * n, ratio * n);
    const ImageArray coarse = resample_pixel_integrated(
        fine, 0.01, 0.04, {fine_model.x, fine_model.y}, n, n, centre);
    ASSERT_LT((coarse - render_stamp(truth, n, n)).abs().maxCoeff(), 1e-14);

    PsfFitOptions options;
    options.residual_target = 1e-5;
    options.beta_tolerance = 1e-9;
    options.centre_tolerance = 1e-10;
    options.centre_iterations = 20;
    const auto start = std::chrono::steady_clock::now();
    const PsfModel psf = fit_psf_image(coarse, options);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    report("known_psf_n_max", psf.n_max);
    report("known_psf_beta_relative_error", psf.model.beta_pix / beta - 1.0);
    report("known_psf_centre_error", std::hypot(psf.model.x - centre.x, psf.model.y - centre.y));
    report("known_psf_max_residual_fraction", psf.max_residual_fraction);
    report("known_psf_fit_seconds", seconds);
    for (const PsfFitStep& s : psf.steps)
        report("known_psf_max_residual_at_n" + std::to_string(s.n_max), s.max_residual_fraction);
    ASSERT_EQ(psf.n_max, n_max);
    EXPECT_TRUE(psf.reached_target);
    EXPECT_NEAR(psf.model.beta_pix, beta, 1e-6 * beta);
    EXPECT_NEAR(psf.model.x, centre.x, 1e-6);
    EXPECT_NEAR(psf.model.y, centre.y, 1e-6);
    const Eigen::VectorXd got = real_parameters(psf.model), want = real_parameters(truth);
    const double coeff_error = (got - want).cwiseAbs().maxCoeff() / want.cwiseAbs().maxCoeff();
    report("known_psf_coefficient_error", coeff_error);
    EXPECT_LT(coeff_error, 1e-6);

    // The record round-trips to the same model.
    const ShapeletRecord record = psf_record(psf, 0.04, "psf");
    EXPECT_NEAR(record.beta, psf.model.beta_pix * 0.04, 1e-15);
    ASSERT_TRUE(record.flux.has_value());
    EXPECT_NEAR(*record.flux, 1.0, 1e-12);
    ASSERT_EQ(record.flags.size(), 1u);
    EXPECT_EQ(record.flags[0], "converged");
    const ShapeletModel back = ShapeletRecord::from_json(record.to_json()).to_model();
    EXPECT_LT((render_stamp(back, n, n) - psf.image).abs().maxCoeff(), 1e-14);
}

TEST(Psf, BadInputIsRefused) {
    PsfFitOptions options;
    EXPECT_THROW(fit_psf_image(ImageArray(), options), Error);
    EXPECT_THROW(fit_psf_image(-ImageArray::Ones(9, 9), options), Error);
    ImageArray nan = ImageArray::Ones(9, 9);
    nan(3, 3) = std::nan("");
    EXPECT_THROW(fit_psf_image(nan, options), Error);
    options.n_max_cap = -1;
    EXPECT_THROW(fit_psf_image(ImageArray::Ones(9, 9), options), Error);
    const ImageArray fine = gaussian_stamp(6.0, 40.0, 40.0, 81, 81);
    EXPECT_THROW(psf_from_oversampled(fine, 0.01, 0.04, {}, 30, {}), Error);  // even stamp
    EXPECT_THROW(psf_from_oversampled(fine, 0.01, 0.04, {0.0}, 31, {}), Error);
    EXPECT_THROW(psf_from_oversampled(fine, 0.0, 0.04, {}, 31, {}), Error);
}

// The acceptance criterion: the shipped TinyTim WFPC2 F814W PSF (300×300 at 0.01″, no
// detector pixel, no drizzle drop) with the WF pixel (0.0996″) and the drizzle drop (pixfrac
// 0.5 → 0.05″) applied, at the HDF pixel scale 0.03985″ in a 41×41 stamp: max |residual| < 1%
// of the peak. Then the raw optics (no boxes) at the same scale, reported.
namespace {
void report_psf(const std::string& name, const PsfModel& psf, double scale, double seconds) {
    report(name + "_n_max", psf.n_max);
    report(name + "_beta_pix", psf.model.beta_pix);
    report(name + "_beta_arcsec", psf.model.beta_pix * scale);
    report(name + "_max_residual_fraction", psf.max_residual_fraction);
    report(name + "_rms_residual_fraction", psf.rms_residual_fraction);
    report(name + "_flux_outside_stamp", psf.flux_outside_stamp);
    report(name + "_beyond_reach_flux_fraction", psf.beyond_reach_flux_fraction);
    report(name + "_beyond_reach_max_residual_fraction", psf.beyond_reach_max_residual_fraction);
    report(name + "_model_flux_over_stamp_flux", psf.model_flux / psf.data_flux);
    report(name + "_fit_seconds", seconds);
    for (const PsfFitStep& s : psf.steps)
        std::cout << "  [measured] " << name << "_step n_max = " << s.n_max
                  << " beta_pix = " << s.beta_pix << " max_residual = " << s.max_residual_fraction
                  << " rms_residual = " << s.rms_residual_fraction
                  << " centroid_offset = " << s.centroid_offset << " fits = " << s.fits << "\n";
}
}  // namespace

TEST(Psf, TinyTimWfpc2F814wAtTheHdfScale) {
    const ImageArray fine = read_fits_image(tinytim_path());
    ASSERT_EQ(fine.rows(), 300);
    ASSERT_EQ(fine.cols(), 300);
    const double fine_scale = 0.01, hdf_scale = 0.03985;
    const std::vector<double> boxes{0.0996, 0.05};
    auto start = std::chrono::steady_clock::now();
    const PsfModel psf = psf_from_oversampled(fine, fine_scale, hdf_scale, boxes, 41, {});
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    report_psf("tinytim_boxed", psf, hdf_scale, seconds);
    EXPECT_LT(psf.max_residual_fraction, 0.01);  // the acceptance criterion
    EXPECT_LE(psf.n_max, 20);
    EXPECT_NEAR(flux(psf.model), 1.0, 1e-12);
    const Moments m = moments(psf.model);
    EXPECT_NEAR(m.x, 21.0, 0.05);  // the stamp is centred on the (whole PSF's) centroid
    EXPECT_NEAR(m.y, 21.0, 0.05);
    const ShapeletRecord record = psf_record(psf, hdf_scale, "wfpc2_f814w");
    EXPECT_EQ(record.flags.at(0), psf.reached_target ? "converged" : "residual_above_target");
    // The default 0.5 % target is missed (0.58 % at n_max 14): from n_max 14 on β sits on its
    // resolution bound β/√(n+1) = 0.5 pixel and the residual is a ±0.5 % checkerboard on the
    // core — power above the 0.04″ Nyquist frequency (λ/D = 0.07″ = 1.75 pixels) aliased by the
    // pixels. A basis allowed to 0.3 pixel follows it.
    PsfFitOptions finer;
    finer.min_resolution_pixels = 0.3;
    start = std::chrono::steady_clock::now();
    const PsfModel fine_basis = psf_from_oversampled(fine, fine_scale, hdf_scale, boxes, 41, finer);
    report_psf("tinytim_boxed_resolution_0.3",
               fine_basis, hdf_scale,
               std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    EXPECT_TRUE(fine_basis.reached_target);
    EXPECT_LT(fine_basis.max_residual_fraction, 0.005);
}

// The raw optics (no detector pixel, no drizzle drop) at the HDF scale: sharper and more
// undersampled, so with the 0.5-pixel resolution bound β is pinned on it from n_max 1 on and
// the core's aliased structure stays in the residual (5.8 % of the peak at best, n_max 6);
// with 0.3 pixel the 0.5 % target is reached. Reported; the bounds below only guard against
// regressions. Orders are capped at 12 here to keep the test quick: orders 13–20 were measured
// at 7.3–9.5 % (β still on the bound), never better than n_max 6.
TEST(Psf, TinyTimRawOpticsAtTheHdfScale) {
    const ImageArray fine = read_fits_image(tinytim_path());
    const double hdf_scale = 0.03985;
    PsfFitOptions options;
    options.n_max_cap = 12;
    auto start = std::chrono::steady_clock::now();
    const PsfModel psf = psf_from_oversampled(fine, 0.01, hdf_scale, {}, 41, options);
    report_psf("tinytim_raw", psf, hdf_scale,
               std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    EXPECT_FALSE(psf.reached_target);
    EXPECT_LT(psf.max_residual_fraction, 0.08);
    PsfFitOptions finer;
    finer.min_resolution_pixels = 0.3;
    start = std::chrono::steady_clock::now();
    const PsfModel fine_basis = psf_from_oversampled(fine, 0.01, hdf_scale, {}, 41, finer);
    report_psf("tinytim_raw_resolution_0.3", fine_basis, hdf_scale,
               std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    EXPECT_TRUE(fine_basis.reached_target);
    EXPECT_LT(fine_basis.max_residual_fraction, 0.005);
}

// The pixel scale of a PSF image: the option, else PIXSCALE (TinyTim), else the WCS of a star
// cut from a field (cfitsio's [x0:x1,y0:y1] keeps it); else an error that names the file.
TEST(Psf, ImagePixelScaleFromOptionHeaderOrWcs) {
    const std::string file = ::testing::TempDir() + "psf_scale.fits";
    const ImageArray star = ImageArray::Constant(9, 9, 1.0);
    {
        FitsWriter out(file, "test");
        out.write_image(star, {"TINYTIM", -32, "", {}, {{"PIXSCALE", 0.01}}, {}});
        out.write_image(star, {"FIELD", -32, "", tan_wcs(10.0, 20.0, 0.04, 5.0, 5.0, 30.0), {}, {}});
        out.write_image(star, {"BARE", -32, "", {}, {}, {}});
        out.commit();
    }
    EXPECT_DOUBLE_EQ(read_psf_image(file + "[TINYTIM]", std::nullopt).pixel_scale, 0.01);
    // The cutout's sky (its border's median, here the constant 1) is removed as it is read.
    const PsfImage flat = read_psf_image(file + "[TINYTIM]", std::nullopt);
    EXPECT_EQ(flat.sky, 1.0);
    EXPECT_EQ(flat.pixels.abs().maxCoeff(), 0.0);
    EXPECT_DOUBLE_EQ(read_psf_image(file + "[TINYTIM]", 0.05).pixel_scale, 0.05);
    EXPECT_NEAR(read_psf_image(file + "[FIELD][2:6,2:6]", std::nullopt).pixel_scale, 0.04, 1e-12);
    try {
        read_psf_image(file + "[BARE]", std::nullopt);
        ADD_FAILURE() << "no Error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("psf_scale.fits[BARE]: no PIXSCALE keyword or WCS"),
                  std::string::npos)
            << e.what();
    }
}
