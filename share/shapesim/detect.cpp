#include "shapesim/detect.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/error.hpp"
#include "shapesim/statistics.hpp"

#include <cstddef>  // sep.h uses size_t without including it
extern "C" {        // sep.h has no C++ guards
#include <sep.h>
}

#include <algorithm>
#include <array>
#include <cstring>
#include <cmath>
#include <limits>
#include <memory>
#include <sstream>

namespace shapesim {

namespace {

// libsep's status text plus its detail buffer (sizes from sep.h's contract: 61 and 512).
std::string sep_message(int status) {
    char message[64] = {};
    char detail[512] = {};
    sep_get_errmsg(status, message);
    sep_get_errdetail(detail);
    std::string text = message;
    if (detail[0] != '\0') text += std::string(" (") + detail + ")";
    return text;
}

void check_sep(int status, const std::string& what) {
    if (status != 0) throw Error(what + ": libsep: " + sep_message(status));
}

struct BackgroundDeleter {
    void operator()(sep_bkg* p) const { sep_bkg_free(p); }
};
struct CatalogDeleter {
    void operator()(sep_catalog* p) const { sep_catalog_free(p); }
};

sep_image sep_view(const ImageArray& data, const ImageArray* sigma, const std::uint8_t* bad,
                   const LabelArray* segmentation) {
    sep_image im{};
    im.data = data.data();
    im.dtype = SEP_TDOUBLE;
    im.w = int(data.cols());
    im.h = int(data.rows());
    if (sigma) {
        im.noise = sigma->data();
        im.ndtype = SEP_TDOUBLE;
        im.noise_type = SEP_NOISE_STDDEV;
    } else {
        im.noise_type = SEP_NOISE_NONE;
    }
    if (bad) {
        im.mask = bad;
        im.mdtype = SEP_TBYTE;
        im.maskthresh = 0.0;
    }
    if (segmentation) {
        static_assert(sizeof(std::int32_t) == sizeof(int), "libsep segmaps are native int");
        im.segmap = segmentation->data();
        im.sdtype = SEP_TINT;
    }
    return im;
}

// FWHM_IMAGE as SExtractor 2.25 computes it (its analyse.c, examineiso): over the object's
// pixels brighter than t0 = max(peak/5, the lowest detection threshold among them), a
// least-squares fit of ln I = c − k r² (r from the isophotal barycentre), each pixel weighted
// by I² (a fit to I itself, linearised); k is kept ≥ 1/(13 a b) (FWHM at most ≈ 6σ of the
// object's own moments); FWHM = 2√(ln 2)/√k, less SExtractor's undersampling correction
// 1/(4 FWHM).
double sextractor_fwhm(const std::vector<std::array<double, 3>>& pixels, double peak,
                       double threshold, double a, double b) {
    const double t0 = std::max(peak / 5.0, threshold);
    if (!(t0 > 0.0)) return 0.0;
    double s = 0.0, sx = 0.0, sy = 0.0, sxx = 0.0, sxy = 0.0;
    for (const auto& [value, dx, dy] : pixels) {
        if (!(value > t0)) continue;
        const double w = value * value, d2 = dx * dx + dy * dy, l = std::log(value);
        s += w;
        sx += d2 * w;
        sxx += d2 * d2 * w;
        sy += l * w;
        sxy += l * d2 * w;
    }
    const double det = s * sxx - sx * sx;
    if (!(std::abs(det) > 0.0)) return 0.0;
    double k = -(s * sxy - sx * sy) / det;
    const double k_min = 1.0 / (13.0 * a * b);
    if (k < k_min) k = k_min;
    double fwhm = 1.6651 / std::sqrt(k);
    if (fwhm > 0.0) fwhm -= 1.0 / (4.0 * fwhm);
    return fwhm;
}

// Correlated-noise factor from 4×4 blocks of sky (see DetectionResult::noise_correlation):
// block sums normalised by √Σσ², their 3σ-clipped rms. Too few blocks (< 20): 1.
double correlated_noise_factor(const DetectionResult& result) {
    constexpr int block = 4;
    const int nx = int(result.image.cols()), ny = int(result.image.rows());
    std::vector<double> z;
    for (int j0 = 0; j0 + block <= ny; j0 += block)
        for (int i0 = 0; i0 + block <= nx; i0 += block) {
            double sum = 0.0, variance = 0.0;
            bool sky = true;
            for (int j = j0; j < j0 + block && sky; ++j)
                for (int i = i0; i < i0 + block; ++i) {
                    if (result.segmentation(j, i) != 0 || result.is_bad(j, i)) {
                        sky = false;
                        break;
                    }
                    sum += result.image(j, i);
                    variance += result.sigma(j, i) * result.sigma(j, i);
                }
            if (sky) z.push_back(sum / std::sqrt(variance));
        }
    if (z.size() < 20) return 1.0;
    const double rms = clipped_sigma(z);
    return rms > 0.0 ? rms : 1.0;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// A 3σ-clipped rms

double clipped_sigma(const std::vector<double>& values) {
    double rms = std::numeric_limits<double>::quiet_NaN();
    double low = -std::numeric_limits<double>::infinity(), high = -low;
    long previous = -1;
    for (int pass = 0; pass < 10; ++pass) {
        double s = 0.0, ss = 0.0;
        long count = 0;
        for (double v : values)
            if (v >= low && v <= high) {
                s += v;
                ss += v * v;
                ++count;
            }
        if (count < 2) return std::numeric_limits<double>::quiet_NaN();
        const double mean = s / double(count);
        rms = std::sqrt(std::max(0.0, ss / double(count) - mean * mean));
        if (count == previous) break;
        previous = count;
        low = mean - 3.0 * rms;
        high = mean + 3.0 * rms;
    }
    // The values kept are those within ±3σ whether or not any fell outside: a sample of the
    // truncated Gaussian, whose σ is 0.98658 of the full one.
    return rms / 0.98658;
}

// ---------------------------------------------------------------------------------------------
// Apertures

namespace {

// SExtractor's MASK_TYPE CORRECT on a cutout: the box of half-widths (half_x, half_y) about
// the 0-based centre (x0, y0), where every pixel that is bad or owned by another object is
// replaced by its mirror image through the centre (value and σ) when that one is usable, else
// by 0 (σ 0). libsep's own masking only rescales the sum by the unmasked area, which
// overestimates a galaxy's flux next to a brighter neighbour (by 7–13% for two equal
// Gaussians 5σ apart), so the apertures run on these cutouts, unmasked.
struct Cutout {
    ImageArray image, sigma;
    int i0 = 0, j0 = 0;       // 0-based image position of the cutout's pixel (0, 0)
    bool masked = false;      // some pixel was replaced
    bool truncated = false;   // the box runs off the image
};

Cutout corrected_cutout(const ImageArray& image, const ImageArray* sigma,
                        const std::uint8_t* bad, const LabelArray* segmentation, int label,
                        double x0, double y0, double half_x, double half_y) {
    const int nx = int(image.cols()), ny = int(image.rows());
    Cutout c;
    c.truncated = x0 - half_x < -0.5 || y0 - half_y < -0.5 || x0 + half_x > nx - 0.5 ||
                  y0 + half_y > ny - 0.5;
    // One spare pixel each side: libsep's sub-pixel overlap reaches the boundary pixels.
    const auto clamp_to = [](double v, int n) {
        return int(std::clamp(v, 0.0, double(n - 1)));
    };
    c.i0 = clamp_to(std::floor(x0 - half_x) - 1, nx);
    c.j0 = clamp_to(std::floor(y0 - half_y) - 1, ny);
    const int i1 = clamp_to(std::ceil(x0 + half_x) + 1, nx);
    const int j1 = clamp_to(std::ceil(y0 + half_y) + 1, ny);
    const int w = i1 - c.i0 + 1, h = j1 - c.j0 + 1;
    c.image = image.block(c.j0, c.i0, h, w);
    c.sigma = sigma ? ImageArray(sigma->block(c.j0, c.i0, h, w)) : ImageArray::Zero(h, w);
    const auto usable = [&](int i, int j) {
        const std::size_t k = std::size_t(j) * std::size_t(nx) + std::size_t(i);
        if (bad && bad[k]) return false;
        if (!segmentation) return true;
        const int owner = segmentation->data()[k];
        return owner == 0 || owner == label;
    };
    for (int j = 0; j < h; ++j)
        for (int i = 0; i < w; ++i) {
            if (usable(c.i0 + i, c.j0 + j)) continue;
            c.masked = true;
            const int mi = int(std::lround(2.0 * x0 - (c.i0 + i)));
            const int mj = int(std::lround(2.0 * y0 - (c.j0 + j)));
            if (mi >= 0 && mj >= 0 && mi < nx && mj < ny && usable(mi, mj)) {
                c.image(j, i) = image(mj, mi);
                c.sigma(j, i) = sigma ? (*sigma)(mj, mi) : 0.0;
            } else {
                c.image(j, i) = 0.0;
                c.sigma(j, i) = 0.0;
            }
        }
    return c;
}

}  // namespace

ApertureFlux circular_aperture_flux(const ImageArray& image, const ImageArray* sigma,
                                    const std::uint8_t* bad, const LabelArray* segmentation,
                                    int label, double x, double y, double radius) {
    require(radius > 0.0 && std::isfinite(radius), "aperture radius must be > 0");
    const Cutout c = corrected_cutout(image, sigma, bad, segmentation, label, x - 1.0, y - 1.0,
                                      radius, radius);
    const sep_image im = sep_view(c.image, sigma ? &c.sigma : nullptr, nullptr, nullptr);
    double sum = 0.0, error = 0.0, area = 0.0;
    short flag = 0;
    check_sep(sep_sum_circle(&im, x - 1.0 - c.i0, y - 1.0 - c.j0, radius, 0, 0, 0, &sum, &error,
                             &area, &flag),
              "circular aperture");
    ApertureFlux out;
    out.flux = sum;
    out.error = sigma ? error : 0.0;
    out.truncated = c.truncated;
    out.masked = c.masked;
    return out;
}

ApertureFlux circular_aperture_flux(const DetectionResult& result, int label, double x,
                                    double y, double radius) {
    ApertureFlux out = circular_aperture_flux(result.image, &result.sigma, result.bad.data(),
                                              &result.segmentation, label, x, y, radius);
    out.error *= result.noise_correlation;
    return out;
}

// ---------------------------------------------------------------------------------------------
// Detection

namespace {

// Step 1 of the header: pixels that are not data (NaN, infinite, the ±1e30 sentinels, zero
// weight) are marked bad and zeroed, so no later step reads them as light.
void mark_bad_pixels(const ImageArray& image, const ImageArray* inverse_variance,
                     DetectionResult& result) {
    const Eigen::Index ny = image.rows(), nx = image.cols();
    const std::size_t n = std::size_t(nx) * std::size_t(ny);
    result.bad.assign(n, 0);
    result.image = image;
    for (Eigen::Index j = 0; j < ny; ++j)
        for (Eigen::Index i = 0; i < nx; ++i) {
            // |value| ≥ 1e30 is a bad-pixel sentinel (SExtractor's −BIG; 1e38 fills), never
            // light: libsep's float moments overflow on it.
            const bool bad = !(std::abs(image(j, i)) < kBadPixelValue) ||
                             (inverse_variance && !((*inverse_variance)(j, i) > 0.0));
            if (bad) {
                result.bad[std::size_t(j * nx + i)] = 1;
                result.image(j, i) = 0.0;
                ++result.bad_pixels;
            }
        }
    if (result.bad_pixels == (long long)n)
        throw Error("no usable pixel: every pixel is NaN/infinite, ±1e30 or beyond, or has zero "
                    "weight");
}

// Without a weight map, a zero-filled region (a rotated mosaic's border, an empty tile)
// says "no data" only by being exactly 0: a pixel that is 0 with all its neighbours 0 is
// bad, so the background and its rms come from the data alone (noise never makes 3×3
// exact zeros in float data; σ ~ 1 DN integer data may lose ~1e-4 of its pixels). An image
// that is 0 everywhere is left to the no-noise error below.
void mark_empty_regions(const ImageArray& image, DetectionResult& result) {
    const Eigen::Index ny = image.rows(), nx = image.cols();
    const std::size_t n = std::size_t(nx) * std::size_t(ny);
    std::vector<std::uint8_t> empty(n, 0);
    long long count = 0;
    for (Eigen::Index j = 0; j < ny; ++j)
        for (Eigen::Index i = 0; i < nx; ++i) {
            bool zero = true;
            for (Eigen::Index b = std::max<Eigen::Index>(j - 1, 0);
                 zero && b <= std::min<Eigen::Index>(j + 1, ny - 1); ++b)
                for (Eigen::Index a = std::max<Eigen::Index>(i - 1, 0);
                     zero && a <= std::min<Eigen::Index>(i + 1, nx - 1); ++a)
                    zero = image(b, a) == 0.0;
            const std::size_t k = std::size_t(j * nx + i);
            if (zero && !result.bad[k]) empty[k] = 1, ++count;
        }
    if (count > 0 && count < (long long)n - result.bad_pixels)
        for (std::size_t k = 0; k < n; ++k)
            if (empty[k]) {
                result.bad[k] = 1;
                ++result.bad_pixels;
                ++result.zero_noise_pixels;
            }
}

// Step 2: SEP's background (mesh, filter, spline) subtracted from the image, its global mean
// and rms kept; bad pixels stay 0. The background is returned for its rms map.
std::unique_ptr<sep_bkg, BackgroundDeleter> subtract_background(DetectionResult& result,
                                                                const DetectionOptions& options) {
    const std::size_t n = result.bad.size();
    std::unique_ptr<sep_bkg, BackgroundDeleter> background;
    {
        const sep_image im = sep_view(result.image, nullptr, result.bad.data(), nullptr);
        sep_bkg* raw = nullptr;
        check_sep(sep_background(&im, options.back_size, options.back_size,
                                 options.back_filter_size, options.back_filter_size, 0.0, &raw),
                  "background");
        background.reset(raw);
    }
    check_sep(sep_bkg_subarray(background.get(), result.image.data(), SEP_TDOUBLE),
              "background subtraction");
    result.background_mean = sep_bkg_global(background.get());
    result.background_rms = sep_bkg_globalrms(background.get());
    for (std::size_t k = 0; k < n; ++k)
        if (result.bad[k]) result.image.data()[k] = 0.0;
    return background;
}

// Step 3 with a weight map: σ = 1/√w, rescaled (--rescale-weight) so the map's median σ is
// the background's measured rms, since drizzle weights are right only up to a factor.
void noise_map_from_weight(const ImageArray& inverse_variance, const DetectionOptions& options,
                           DetectionResult& result) {
    const std::size_t n = result.bad.size();
    constexpr double infinite = std::numeric_limits<double>::infinity();
    std::vector<double> sigmas;
    sigmas.reserve(n);
    for (std::size_t k = 0; k < n; ++k)
        if (!result.bad[k]) sigmas.push_back(1.0 / std::sqrt(inverse_variance.data()[k]));
    const double median_sigma = upper_median(sigmas);
    if (options.rescale_weight) {
        if (!(result.background_rms > 0.0))
            throw Error("background rms is zero: cannot rescale the weight map "
                        "(a constant image?)");
        result.weight_scale = std::pow(median_sigma / result.background_rms, 2);
    }
    const double scale = std::sqrt(result.weight_scale);
    for (std::size_t k = 0; k < n; ++k)
        result.sigma.data()[k] =
            result.bad[k] ? infinite : 1.0 / (std::sqrt(inverse_variance.data()[k]) * scale);
}

// Step 3 without a weight map: SEP's local background rms.
void noise_map_from_background(sep_bkg* background, DetectionResult& result) {
    const std::size_t n = result.bad.size();
    constexpr double infinite = std::numeric_limits<double>::infinity();
    check_sep(sep_bkg_rmsarray(background, result.sigma.data(), SEP_TDOUBLE),
              "background rms");
    // Where the local rms is zero the image is constant: a zero-filled border around a
    // rotated mosaic, an empty tile. Nothing can be detected there; those pixels are bad,
    // and only an image with no noise anywhere is an error.
    for (std::size_t k = 0; k < n; ++k) {
        if (result.bad[k]) {
            result.sigma.data()[k] = infinite;
        } else if (!(result.sigma.data()[k] > 0.0)) {
            result.bad[k] = 1;
            result.image.data()[k] = 0.0;
            result.sigma.data()[k] = infinite;
            ++result.bad_pixels;
            ++result.zero_noise_pixels;
        }
    }
    if (result.bad_pixels == (long long)n)
        throw Error("background rms is zero: the image has no noise (a constant image?); "
                    "give a weight map");
}

// Steps 1–3 of the header: bad pixels, background subtracted, the noise map (objects,
// segmentation and the correlated-noise factor left to the caller).
DetectionResult noise_field(const ImageArray& image, const ImageArray* inverse_variance,
                            const DetectionOptions& options) {
    const Eigen::Index ny = image.rows(), nx = image.cols();
    require(nx > 0 && ny > 0, "image is empty");
    if (inverse_variance && (inverse_variance->rows() != ny || inverse_variance->cols() != nx)) {
        std::ostringstream s;
        s << "weight map is " << inverse_variance->cols() << "×" << inverse_variance->rows()
          << " pixels but the image is " << nx << "×" << ny;
        throw Error(s.str());
    }

    DetectionResult result;
    mark_bad_pixels(image, inverse_variance, result);
    if (!inverse_variance) mark_empty_regions(image, result);
    const auto background = subtract_background(result, options);
    result.sigma.resize(ny, nx);
    if (inverse_variance)
        noise_map_from_weight(*inverse_variance, options, result);
    else
        noise_map_from_background(background.get(), result);
    return result;
}

// libsep reads the noise array at masked pixels too: give it finite values there.
ImageArray sep_noise(const DetectionResult& result) {
    ImageArray sep_sigma = result.sigma;
    for (std::size_t k = 0; k < result.bad.size(); ++k)
        if (result.bad[k]) sep_sigma.data()[k] = std::numeric_limits<float>::max();
    return sep_sigma;
}

// An AUTO aperture in libsep's 0-based pixels: the ellipse r·(a, b) at θ (radians).
struct AutoAperture {
    int label = 0;
    double x0 = 0.0, y0 = 0.0, a = 0.0, b = 0.0, theta = 0.0, radius = 0.0;
};

// FLUX_AUTO in `ap` on `result`'s image, neighbours' pixels mirrored out; the error from σ
// times the correlated-noise factor, plus Poisson with GAIN.
ApertureFlux auto_flux(const DetectionResult& result, const ImageArray& sep_sigma,
                       const AutoAperture& ap, const DetectionOptions& options) {
    const double theta = ap.theta, a_ap = ap.a, b_ap = ap.b, radius = ap.radius;
    const double x0 = ap.x0, y0 = ap.y0;
    const Cutout c = corrected_cutout(
        result.image, &sep_sigma, result.bad.data(), &result.segmentation, ap.label, x0, y0,
        radius * std::hypot(a_ap * std::cos(theta), b_ap * std::sin(theta)),
        radius * std::hypot(a_ap * std::sin(theta), b_ap * std::cos(theta)));
    const sep_image ci = sep_view(c.image, &c.sigma, nullptr, nullptr);
    double sum = 0.0, error = 0.0, area = 0.0;
    short flag = 0;
    check_sep(sep_sum_ellipse(&ci, x0 - c.i0, y0 - c.j0, a_ap, b_ap, theta, radius, 0, 0, 0,
                              &sum, &error, &area, &flag),
              "AUTO flux of object " + std::to_string(ap.label));
    ApertureFlux out;
    out.flux = sum;
    out.error = error * result.noise_correlation;
    if (options.gain > 0.0 && sum > 0.0)
        out.error = std::sqrt(out.error * out.error + sum / options.gain);
    out.truncated = c.truncated;
    out.masked = c.masked;
    return out;
}

}  // namespace

namespace {

// Step 4 of the header: libsep's extraction above the threshold; the pixel stack grows when a
// large image needs it.
std::unique_ptr<sep_catalog, CatalogDeleter> extract_objects(const DetectionResult& result,
                                                             const ImageArray& sep_sigma,
                                                             const DetectionOptions& options) {
    const std::size_t n = result.bad.size();
    std::unique_ptr<sep_catalog, CatalogDeleter> catalog;
    const sep_image im = sep_view(result.image, &sep_sigma, result.bad.data(), nullptr);
    std::size_t stack = std::max<std::size_t>(300000, n / 4);
    for (int attempt = 0;; ++attempt) {
        sep_set_extract_pixstack(stack);
        sep_catalog* raw = nullptr;
        const int status = sep_extract(
            &im, float(options.detect_thresh), SEP_THRESH_REL, options.min_area,
            options.filter.values.data(), options.filter.nx, options.filter.ny,
            options.filter_mode == FilterMode::matched ? SEP_FILTER_MATCHED
                                                       : SEP_FILTER_CONV,
            options.deblend_nthresh, options.deblend_mincont, options.clean ? 1 : 0,
            options.clean_param, &raw);
        if (status == 0) {
            catalog.reset(raw);
            break;
        }
        // Status 2 is libsep's PIXSTACK_FULL ("internal pixel buffer full"): retry with
        // a bigger stack.
        if (status == 2 && attempt < 4 && stack < n) {
            stack = std::min(stack * 4, n);
            continue;
        }
        check_sep(status, "extraction");
    }
    return catalog;
}

// The segmentation map from the objects' pixel lists: object k is label k + 1, 0 is sky.
LabelArray segmentation_map(const sep_catalog& cat, Eigen::Index ny, Eigen::Index nx) {
    LabelArray segmentation = LabelArray::Zero(ny, nx);
    for (int k = 0; k < cat.nobj; ++k)
        for (int p = 0; p < cat.npix[k]; ++p) segmentation.data()[cat.pix[k][p]] = k + 1;
    return segmentation;
}

// Object k's θ, radians. libsep stores θ as a float: float(π/2) read back exceeds π/2, which
// its own aperture functions then reject. Clamp once, to (−π/2, π/2].
double sep_theta(const sep_catalog& cat, int k) {
    double theta = std::clamp(double(cat.theta[k]), -0.5 * pi, 0.5 * pi);
    if (theta == -0.5 * pi) theta = 0.5 * pi;
    return theta;
}

// Object k as libsep found it, in FITS pixels (1-based), with its flags.
Detection catalog_detection(const sep_catalog& cat, int k, const DetectionResult& result,
                            const DetectionOptions& options) {
    Detection d;
    d.label = k + 1;
    d.x = cat.x[k] + 1.0;
    d.y = cat.y[k] + 1.0;
    d.x_peak = cat.xpeak[k] + 1;
    d.y_peak = cat.ypeak[k] + 1;
    d.xmin = cat.xmin[k] + 1;
    d.xmax = cat.xmax[k] + 1;
    d.ymin = cat.ymin[k] + 1;
    d.ymax = cat.ymax[k] + 1;
    d.a = cat.a[k];
    d.b = cat.b[k];
    d.theta = sep_theta(cat, k) * 180.0 / pi;
    d.cxx = cat.cxx[k];
    d.cyy = cat.cyy[k];
    d.cxy = cat.cxy[k];
    d.flux_iso = cat.flux[k];
    d.peak = cat.peak[k];
    d.npix = cat.npix[k];
    d.sigma = result.sigma(cat.ypeak[k], cat.xpeak[k]);
    d.threshold = options.detect_thresh * d.sigma;
    if (cat.flag[k] & SEP_OBJ_MERGED) d.flags.push_back("blended");
    if (cat.flag[k] & SEP_OBJ_TRUNC) d.flags.push_back("truncated");
    if (cat.flag[k] & SEP_OBJ_SINGU) d.flags.push_back("singular");
    return d;
}

// Isophotal area above the analysis threshold on the image; the FWHM from the object's pixels
// (SExtractor's fit, sextractor_fwhm), the threshold its lowest per pixel. `pixels` is a
// workspace reused across objects.
void measure_iso_and_fwhm(Detection& d, const sep_catalog& cat, int k,
                          const DetectionResult& result, const DetectionOptions& options,
                          std::vector<std::array<double, 3>>& pixels) {
    pixels.clear();
    double lowest = std::numeric_limits<double>::infinity();
    const int nx = int(result.image.cols());
    for (int p = 0; p < cat.npix[k]; ++p) {
        const int pixel = cat.pix[k][p];
        const double value = result.image.data()[pixel], sigma = result.sigma.data()[pixel];
        if (value > options.analysis_thresh * sigma) ++d.iso_area;
        lowest = std::min(lowest, options.detect_thresh * sigma);
        pixels.push_back({value, double(pixel % nx) - cat.x[k], double(pixel / nx) - cat.y[k]});
    }
    d.fwhm = sextractor_fwhm(pixels, cat.peak[k], lowest, cat.a[k], cat.b[k]);
    // An unresolved spike (a hot pixel, a cosmic ray) has a fitted core narrower than the
    // undersampling correction: no FWHM, flagged, and the catalogue goes on (issue 15).
    if (!(d.fwhm > 0.0) || !std::isfinite(d.fwhm)) {
        d.fwhm = std::numeric_limits<double>::quiet_NaN();
        d.flags.push_back("fwhm_failed");
    }
}

// Kron radius within 6 a (SExtractor), then the AUTO ellipse, each on a cutout with the
// neighbours mirrored out.
void measure_auto(Detection& d, const sep_catalog& cat, int k, const DetectionResult& result,
                  const ImageArray& sep_sigma, const DetectionOptions& options) {
    const double theta = sep_theta(cat, k);
    const double x0 = cat.x[k], y0 = cat.y[k];
    // A degenerate ellipse (a line of pixels) still needs a usable aperture.
    const double a_ap = std::max(d.a, 0.5), b_ap = std::max(d.b, 0.5);
    // Half-extents of the ellipse of semi-axes (r a, r b) at angle θ.
    const auto half_x = [&](double r) {
        return r * std::hypot(a_ap * std::cos(theta), b_ap * std::sin(theta));
    };
    const auto half_y = [&](double r) {
        return r * std::hypot(a_ap * std::sin(theta), b_ap * std::cos(theta));
    };
    double kron = 0.0;
    short flag = 0;
    {
        const Cutout c = corrected_cutout(result.image, nullptr, result.bad.data(),
                                          &result.segmentation, d.label, x0, y0,
                                          half_x(6.0), half_y(6.0));
        const sep_image ci = sep_view(c.image, nullptr, nullptr, nullptr);
        check_sep(sep_kron_radius(&ci, x0 - c.i0, y0 - c.j0, d.cxx, d.cyy, d.cxy, 6.0, 0,
                                  &kron, &flag),
                  "Kron radius of object " + std::to_string(d.label));
    }
    if (!(kron > 0.0) || !std::isfinite(kron)) kron = 0.0;
    d.kron_radius = kron;
    const double radius = std::max(options.kron_factor * kron, options.kron_min_radius);
    const ApertureFlux automatic =
        auto_flux(result, sep_sigma, {d.label, x0, y0, a_ap, b_ap, theta, radius}, options);
    d.flux_auto = automatic.flux;
    d.flux_auto_err = automatic.error;
    if (automatic.truncated) d.flags.push_back("aperture_truncated");
    if (automatic.masked) d.flags.push_back("aperture_masked");
}

}  // namespace

DetectionResult detect_sources(const ImageArray& image, const ImageArray* inverse_variance,
                               const DetectionOptions& options) {
    options.validate();
    DetectionResult result = noise_field(image, inverse_variance, options);
    const ImageArray sep_sigma = sep_noise(result);
    const auto catalog = extract_objects(result, sep_sigma, options);
    const sep_catalog& cat = *catalog;
    result.segmentation = segmentation_map(cat, image.rows(), image.cols());
    result.noise_correlation = correlated_noise_factor(result);

    // Measurements.
    result.objects.reserve(std::size_t(cat.nobj));
    std::vector<std::array<double, 3>> pixels;
    for (int k = 0; k < cat.nobj; ++k) {
        Detection d = catalog_detection(cat, k, result, options);
        // Saturated: a pixel of the object's, as read, at or above the level (SExtractor's
        // FLAGS bit 4); its shape and flux are not the object's.
        if (std::isfinite(options.saturation))
            for (int p = 0; p < cat.npix[k]; ++p)
                if (image.data()[cat.pix[k][p]] >= options.saturation) {
                    d.flags.push_back("saturated");
                    break;
                }
        measure_iso_and_fwhm(d, cat, k, result, options, pixels);
        measure_auto(d, cat, k, result, sep_sigma, options);
        result.objects.push_back(std::move(d));
    }
    return result;
}


DetectionResult band_field(const ImageArray& image, const ImageArray* inverse_variance,
                           const DetectionOptions& options, const DetectionResult& detection) {
    options.validate();
    if (image.rows() != detection.image.rows() || image.cols() != detection.image.cols()) {
        std::ostringstream s;
        s << "the band image is " << image.cols() << "×" << image.rows()
          << " pixels but the detection image " << detection.image.cols() << "×"
          << detection.image.rows();
        throw Error(s.str());
    }
    DetectionResult result = noise_field(image, inverse_variance, options);
    result.segmentation = detection.segmentation;
    result.noise_correlation = correlated_noise_factor(result);
    return result;
}

std::vector<ApertureFlux> forced_auto_fluxes(const DetectionResult& band,
                                             const std::vector<Detection>& objects,
                                             const DetectionOptions& options) {
    const ImageArray sep_sigma = sep_noise(band);
    std::vector<ApertureFlux> out;
    out.reserve(objects.size());
    for (const Detection& d : objects) {
        const AutoAperture ap{
            d.label,
            d.x - 1.0,
            d.y - 1.0,
            std::max(d.a, 0.5),
            std::max(d.b, 0.5),
            d.theta * pi / 180.0,
            std::max(options.kron_factor * d.kron_radius, options.kron_min_radius)};
        out.push_back(auto_flux(band, sep_sigma, ap, options));
    }
    return out;
}

}  // namespace shapesim
