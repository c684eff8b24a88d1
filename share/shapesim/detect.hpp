// Source detection and photometry on a real image: the SExtractor algorithms through
// Debian's libsep (Barbary 2016, JOSS 1, 58; Bertin & Arnouts 1996, A&AS 117, 393).
//
// Steps, as SExtractor does them and with its parameter names (DESIGN §4 gives the method's
// HDF values, the defaults here):
//   1. Bad pixels: NaN/inf image values and weights ≤ 0 (or NaN) are masked everywhere.
//   2. Background: a mesh of BACK_SIZE² tiles, σ-clipped mode per tile, median-filtered over
//      BACK_FILTERSIZE² tiles, bicubic spline between tiles; subtracted from the image.
//   3. Noise for the threshold: with a weight map, σ = 1/√w. The weight map is first rescaled
//      so that its median σ equals the measured background rms, as SExtractor does for
//      WEIGHT_TYPE MAP_WEIGHT: drizzled images (the HDF) have correlated noise, so their
//      nominal weights misstate the pixel-to-pixel rms (by ≈ 2 in the HDF). Without a weight
//      map, σ is the background rms map.
//   4. Detection: the image is convolved with FILTER (default: SExtractor's 3×3 pyramid)
//      and pixels above DETECT_THRESH·σ are grouped into 8-connected objects of at least
//      DETECT_MINAREA pixels, deblended over DEBLEND_NTHRESH levels with DEBLEND_MINCONT and
//      cleaned (CLEAN_PARAM). The objects' pixels give the segmentation map.
//   5. Per object: isophotal barycentre, second moments → a, b, θ; peak; isophotal area above
//      ANALYSIS_THRESH·σ on the unfiltered image; FWHM as SExtractor 2.25 fits it (ln I
//      against r² over the pixels above max(peak/5, threshold), weights I²); Kron ("AUTO") flux in
//      an ellipse of PHOT_AUTOPARAMS (2.5 r_Kron, at least 3.5) a × b, neighbours' pixels replaced
//      by their mirror images (MASK_TYPE CORRECT); flux error from σ, times the measured
//      correlated-noise factor (drizzling correlates neighbouring pixels, so √Σσ² alone understates
//      it), plus Poisson with GAIN.
//
// Positions in Detection are FITS pixel coordinates (first pixel centred at (1, 1)), like
// X_IMAGE; libsep's 0-based values are shifted once, here.
#pragma once

#include "shapesim/image.hpp"

#include <cstdint>
#include <iosfwd>
#include <limits>
#include <string>
#include <vector>

namespace shapesim {

/// Integer label image: 0 = sky, k = pixel of the object with label k (SEGMENTATION).
using LabelArray = Eigen::Array<std::int32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// A detection filter (SExtractor `.conv` file).
struct FilterKernel {
    std::string name;           ///< file name or "default" (for messages and headers)
    int nx = 0, ny = 0;         ///< width (columns) and height (rows)
    std::vector<float> values;  ///< row-major, ny × nx, as written in the file
};

/// SExtractor's default.conv: the 3×3 pyramid 1 2 1 / 2 4 2 / 1 2 1.
FilterKernel default_filter_kernel();
/// Parse a SExtractor `.conv` file: a first line `CONV NORM` or `CONV NONORM`, `#` comments,
/// then rows of numbers (all rows the same length). Normalisation does not change detection
/// (the threshold applies to the kernel-normalised image), so both kinds are accepted.
/// Errors name `name` and the line.
FilterKernel parse_filter_kernel(std::istream& in, const std::string& name);
FilterKernel read_filter_kernel(const std::string& path);

/// What a noise map holds.
enum class NoiseMapType { weight, rms, variance };
/// Parse "weight" | "rms" | "variance" (Error otherwise).
NoiseMapType parse_noise_map_type(const std::string& text);

/// Inverse variance from a noise map of `type`: 0 where the map flags a bad pixel (weight
/// ≤ 0 is an error unless exactly 0; rms/variance 0 or ∞ → 0; NaN → 0). Negative values
/// throw Error naming `place` and the first offending pixel (FITS x, y).
ImageArray inverse_variance_from(const ImageArray& map, NoiseMapType type,
                                 const std::string& place);

/// How the detection filter is applied (libsep's filter_type).
enum class FilterMode {
    convolution,  ///< SExtractor: threshold on the convolved image in units of the pixel σ
    matched,      ///< libsep's noise-aware matched filter (threshold in units of its own σ)
};

/// Detection parameters (SExtractor names in the comments; defaults = the method's HDF run).
struct DetectionOptions {
    double detect_thresh = 1.3;     ///< DETECT_THRESH, σ
    double analysis_thresh = 0.9;   ///< ANALYSIS_THRESH, σ (isophotal area, FWHM)
    int min_area = 5;               ///< DETECT_MINAREA, pixels
    int deblend_nthresh = 32;       ///< DEBLEND_NTHRESH
    double deblend_mincont = 0.03;  ///< DEBLEND_MINCONT
    bool clean = true;              ///< CLEAN
    double clean_param = 1.0;       ///< CLEAN_PARAM
    int back_size = 64;             ///< BACK_SIZE, pixels
    int back_filter_size = 3;       ///< BACK_FILTERSIZE, tiles
    FilterKernel filter = default_filter_kernel();  ///< FILTER_NAME
    FilterMode filter_mode = FilterMode::convolution;
    bool rescale_weight = true;     ///< scale the weight map to the measured rms (step 3)
    double kron_factor = 2.5;       ///< PHOT_AUTOPARAMS[0]
    double kron_min_radius = 3.5;   ///< PHOT_AUTOPARAMS[1], in units of a, b
    double gain = 0.0;              ///< GAIN, e⁻ per image unit (0: background noise only)
    /// SATUR_LEVEL, in the image's units as read (sky included): an object with a pixel at or
    /// above it is flagged "saturated" (∞: no level).
    double saturation = std::numeric_limits<double>::infinity();

    /// Throws Error (field = SExtractor name) for values out of range.
    void validate() const;
};

/// One detected object (SExtractor meanings).
struct Detection {
    int label = 0;                        ///< NUMBER, also its value in the segmentation map
    double x = 0.0, y = 0.0;              ///< X_IMAGE, Y_IMAGE: isophotal barycentre
    int x_peak = 0, y_peak = 0;           ///< XPEAK_IMAGE, YPEAK_IMAGE (FITS pixels)
    int xmin = 0, xmax = 0, ymin = 0, ymax = 0;  ///< bounding box (FITS pixels)
    double a = 0.0, b = 0.0;              ///< A_IMAGE, B_IMAGE: rms along the axes, pixels
    double theta = 0.0;                   ///< THETA_IMAGE, degrees CCW from +x, (−90, 90]
    double cxx = 0.0, cyy = 0.0, cxy = 0.0;  ///< ellipse coefficients (CXX_IMAGE …)
    double flux_iso = 0.0;                ///< FLUX_ISO: sum over the object's pixels
    double flux_auto = 0.0;               ///< FLUX_AUTO
    double flux_auto_err = 0.0;           ///< FLUXERR_AUTO
    double kron_radius = 0.0;             ///< KRON_RADIUS, units of a, b
    double fwhm = 0.0;                    ///< FWHM_IMAGE, pixels (Gaussian core); NaN and the
                                          ///< flag "fwhm_failed" when the fit gives none > 0
    int iso_area = 0;                     ///< ISOAREA_IMAGE: pixels above ANALYSIS_THRESH
    int npix = 0;                         ///< pixels in the segmentation map
    double peak = 0.0;                    ///< FLUX_MAX, background-subtracted
    double sigma = 0.0;                   ///< pixel noise σ at the peak (rescaled map)
    double threshold = 0.0;               ///< detection threshold at the peak, image units
    std::vector<std::string> flags;       ///< "blended", "truncated", "aperture_truncated",
                                          ///< "aperture_masked", "singular", "fwhm_failed"
};

/// Everything detection produced; later stages (stamps, stellarity) read from it.
struct DetectionResult {
    std::vector<Detection> objects;  ///< in libsep's order; label = index + 1
    ImageArray image;                ///< background-subtracted image, bad pixels 0
    ImageArray sigma;                ///< pixel noise used for the threshold (∞ where bad)
    LabelArray segmentation;         ///< 0 sky, label of the object owning the pixel
    std::vector<std::uint8_t> bad;   ///< 1 where the pixel is bad (row-major like image)
    double background_mean = 0.0;    ///< global background level, image units
    double background_rms = 0.0;     ///< global background rms, image units
    double weight_scale = 1.0;       ///< factor applied to the weight map in step 3
    /// Correlated-noise factor: the rms of flux sums over 4×4 sky blocks (no object, no bad
    /// pixel) over what independent pixels give, √Σσ². 1 for white noise, ≈ 2 for the
    /// drizzled HDF. Aperture flux errors (FLUXERR_AUTO, circular_aperture_flux) include it.
    double noise_correlation = 1.0;
    long long bad_pixels = 0;
    /// Pixels made bad as no data (no weight map only): exactly 0 with every neighbour 0, or
    /// where the local background rms is zero: a zero-filled mosaic border, an empty tile.
    /// Counted in bad_pixels too.
    long long zero_noise_pixels = 0;

    bool is_bad(int row, int column) const {
        return bad[std::size_t(row) * std::size_t(image.cols()) + std::size_t(column)] != 0;
    }
};

/// Standard deviation of `values` after 3σ clipping about the mean (at most 10 passes),
/// divided by 0.98658, the σ a ±3σ cut leaves of a Gaussian, so that Gaussian noise gives
/// its own σ. NaN for fewer than two values. For noise levels from sky pixels: faint wings
/// and cosmic rays do not set them.
double clipped_sigma(const std::vector<double>& values);

/// A detection whose brightest pixel holds at least this share of its isophotal flux is a
/// single-pixel event (a cosmic ray, a hot pixel): no optics puts 75% of a source's light in
/// one pixel (a critically sampled PSF puts ≤ 25%, the undersampled WFPC2 ≤ 45%; the HDF's
/// detections reach 0.47, the corpus's hot pixels 0.98–1.01).
constexpr double kSinglePixelPeakShare = 0.75;
/// True for a single-pixel event (kSinglePixelPeakShare): neither a star nor a galaxy.
inline bool is_single_pixel_event(double peak, double flux_iso) {
    return flux_iso > 0.0 && peak >= kSinglePixelPeakShare * flux_iso;
}

/// Pixel values of this magnitude or more are bad pixels, as NaN and ±Inf are: sentinels
/// (SExtractor's −BIG = −1e30, fills near the float maximum), never light.
constexpr double kBadPixelValue = 1e30;

/// Detect and measure the objects of `image` (any values; NaN, ±Inf and |value| ≥
/// kBadPixelValue = bad). `inverse_variance`
/// (same size, ≥ 0, 0 = bad) may be null. Errors: sizes differ, no good pixel, libsep
/// failures (with libsep's message). An image with nothing above threshold gives an empty
/// `objects`, not an error.
DetectionResult detect_sources(const ImageArray& image, const ImageArray* inverse_variance,
                               const DetectionOptions& options);

/// Flux in an aperture.
struct ApertureFlux {
    double flux = 0.0, error = 0.0;  ///< image units; error from the σ map (0 without one)
    bool truncated = false;          ///< the aperture runs off the image
    bool masked = false;             ///< neighbours' pixels were mirrored
};
/// Flux within `radius` pixels of FITS (x, y) on `image`, sub-pixel exact. Pixels flagged in
/// `bad` (row-major, 1 = bad) and, with `segmentation`, pixels of labels other than `label`
/// (and not 0) are replaced by their mirror image through the centre (SExtractor MASK_TYPE
/// CORRECT); with `sigma` the error is √Σσ². Each of the three may be null.
ApertureFlux circular_aperture_flux(const ImageArray& image, const ImageArray* sigma,
                                    const std::uint8_t* bad, const LabelArray* segmentation,
                                    int label, double x, double y, double radius);
/// The same on a detection's background-subtracted image, σ map and segmentation.
ApertureFlux circular_aperture_flux(const DetectionResult& result, int label, double x,
                                    double y, double radius);

// Dual-image mode (SExtractor's `sex detection.fits,band.fits`): detect once, on a detection
// image, and measure every band of the same pixel grid in the detection's apertures, so that
// colours compare like with like.

/// Another band's field on the detection's pixel grid: steps 1–3 on `image` (its own bad
/// pixels, background, rescaled noise map) with `detection`'s segmentation, and its own
/// correlated-noise factor measured on the sky that segmentation leaves. `objects` is empty:
/// they are the detection's. Error when the sizes differ.
DetectionResult band_field(const ImageArray& image, const ImageArray* inverse_variance,
                           const DetectionOptions& options, const DetectionResult& detection);
/// FLUX_AUTO of each of `objects` (detected elsewhere) on `band`: each detection's own ellipse
/// and Kron radius, neighbours mirrored out by the detection's segmentation, errors from the
/// band's noise (and `options.gain`).
std::vector<ApertureFlux> forced_auto_fluxes(const DetectionResult& band,
                                             const std::vector<Detection>& objects,
                                             const DetectionOptions& options);

}  // namespace shapesim
