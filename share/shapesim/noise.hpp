// The sky's noise as a real image has it, and as a simulation draws it (issue 14 §5).
//
// Measured (measure_sky_noise), on the sky of a detected field: the pixels no detected object
// of S/N ≥ `mask_snr` (4) owns and no bad pixel touches within `grow` pixels (a square dilation of
// the segmentation, so faint wings just outside the isophote do not count), clipped at 5 MAD-σ
// about their median (cosmic rays, hot pixels). Fainter detections stay in: most are the
// noise's own peaks, and masking them would lower the rms and the correlation measured, more
// so the more of them a threshold finds (pure correlated noise: −7% and −0.07 at 2 px). From
// them:
//   rms         their standard deviation (image units);
//   mad_sigma   1.4826 × their median absolute deviation;
//   correlation ξ(dx, dy) = ⟨n(p) n(p + d)⟩ / ⟨n²⟩ over the pairs whose two pixels are both
//               sky, |dx|, |dy| ≤ radius — the 2-D normalised autocorrelation GalSim's
//               CorrelatedNoise takes from a blank image (ξ(0, 0) = 1, ξ(−d) = ξ(d));
//   quantiles   of the pixels on a sparse grid (every `decimate`-th pixel in x and y, far
//               enough apart to be nearly independent), for a two-sample KS test of one
//               sky's pixel histogram against another's (sky_ks).
//
// Drawn (correlated_noise_kernel): white noise convolved with a kernel k whose
// autocorrelation k ⋆ k is ξ: the power spectrum P = DFT(ξ) on an N×N grid (negative
// values, from measurement noise and the cut at `radius`, set to 0), k = DFT⁻¹(√P) (real and
// symmetric), cut to the smallest radius K holding all but `tolerance`² of Σk², normalised
// to Σk² = 1 (the per-pixel variance is the rms²), and stored as the fewest separable terms
// k = Σ_r c_r ⊗ r_r (SVD) that leave out at most `tolerance`² of it: its correlation is ξ to
// ≈ 2·tolerance at every lag; the render's cost per pixel is 2 · (2K + 1) · terms
// multiply-adds. With a marginal, each correlated deviate z is then mapped to T(z), the sky
// value of the same probability (SkyMarginal): the field's pixels have the real sky's
// histogram, tails and all, and nearly its correlation (a monotone map of a Gaussian field
// near the identity: on the HDF's sky ξ moves by ≤ 0.002 at any lag).
#pragma once

#include "shapesim/correlation.hpp"
#include "shapesim/detect.hpp"
#include "shapesim/jsonl.hpp"

#include <array>
#include <iosfwd>
#include <string>
#include <vector>

namespace shapesim {

/// A sky's standardised pixel distribution as a map from standard normal deviates (see the
/// header comment): T(z0 + k·dz) = values[k], linear between, and beyond the table along the
/// mean slope of its last `tail_steps` steps at either end.
struct SkyMarginal {
    static constexpr int tail_steps = 10;
    double z0 = 0.0, dz = 0.0;
    std::vector<double> values;
    bool empty() const { return values.empty(); }
    /// T(z) (inline: render maps every pixel through it).
    double operator()(double z) const {
        const std::size_t n = values.size();
        const double at = (z - z0) * (1.0 / dz);
        if (at >= 0.0 && at < double(n - 1)) {
            const std::size_t k = std::size_t(at);
            return values[k] + (at - double(k)) * (values[k + 1] - values[k]);
        }
        // Beyond the table: along the mean slope of its last tail_steps steps.
        const std::size_t s = std::size_t(tail_steps);
        if (at < 0.0) return values[0] + at * (values[s] - values[0]) / double(s);
        return values[n - 1] +
               (at - double(n - 1)) * (values[n - 1] - values[n - 1 - s]) / double(s);
    }
    /// out[i] = T(in[i]) for i < count, rounded to float (a row of deviates).
    void map(const float* in, float* out, long count) const;
    /// Error naming the field unless dz is within [0.001, 1], z0 within [−10, 0), the values
    /// ascending and within ±100, more than tail_steps and at most 20001 of them.
    void validate() const;
    Json to_json() const;
    static SkyMarginal from_json(const Json& j);
};

/// The measured sky noise of an image (`shapesim.noise/1`, from shapesim-detect).
struct NoiseRecord {
    static constexpr const char* schema = "shapesim.noise/1";
    std::string id = "sky";
    double rms = 0.0;                  ///< image units
    double mad_sigma = 0.0;            ///< image units
    long pixels = 0;                   ///< sky pixels used
    double noise_correlation = 1.0;    ///< F of 4×4 blocks (DetectionResult, for reference)
    NoiseCorrelation correlation;
    std::vector<double> quantiles;     ///< of the decimated sky pixels, at (i + ½)/count
    long quantile_pixels = 0;          ///< how many pixels the quantiles summarise
    SkyMarginal marginal;              ///< empty: Gaussian (a record from before it)
    Json extra = Json::object();

    static NoiseRecord from_json(const Json& record);
    Json to_json() const;
    void validate() const;
};

/// The one record of a noise-model file (Error naming the file and line otherwise).
NoiseRecord read_noise_record(const std::string& path);

struct SkyNoiseOptions {
    int radius = 8;      ///< lags measured, pixels
    int grow = 2;        ///< pixels kept clear of every object and bad pixel
    int decimate = 4;    ///< the quantiles' pixel grid spacing
    int quantiles = 1000;
    /// Only objects of at least this S/N (FLUX_AUTO / FLUXERR_AUTO) are masked (0: all).
    double mask_snr = 4.0;
    double marginal_step = 0.05;      ///< the marginal's dz
    long marginal_tail_pixels = 20;   ///< sky pixels beyond its outermost levels, at least
};

/// Measure the sky noise of a detected field (its background-subtracted image,
/// segmentation and bad pixels). Error when fewer than 100 sky pixels remain.
NoiseRecord measure_sky_noise(const DetectionResult& field, const SkyNoiseOptions& options = {});

/// A noise kernel as a sum of separable terms: k(dx, dy) = Σ_r columns[r][dy + K] rows[r][dx + K].
struct NoiseKernel {
    int radius = 0;  ///< K
    std::vector<std::vector<double>> columns, rows;
    /// The dense (2K + 1)² kernel, row-major by dy.
    std::vector<double> dense() const;
    /// Its autocorrelation Σ_p k(p) k(p + d), |dx|, |dy| ≤ `radius` (0 beyond 2K).
    NoiseCorrelation correlation(int radius) const;
};

/// The kernel drawing noise of correlation `xi` (see the header comment).
NoiseKernel correlated_noise_kernel(const NoiseCorrelation& xi, double tolerance = 2e-3);

/// The edge weight e of the drizzle-like 3×3 kernel [e, 1, e] ⊗ [e, 1, e] for a
/// correlated-noise factor F ≥ 1 (4×4 blocks); 0 for F = 1. Throws Error when F exceeds what a
/// 3×3 kernel can reach (use a measured correlation instead).
double correlated_noise_kernel_edge(double factor);
/// That kernel, normalised to Σk² = 1 (one separable term; radius 0 for F = 1).
NoiseKernel drizzle_noise_kernel(double factor);

/// One sky against another: their autocorrelations, rms and pixel histograms.
struct SkyComparison {
    int radius = 0;
    std::vector<double> difference;  ///< ξ_b − ξ_a, as NoiseCorrelation::values
    double max_difference = 0.0;     ///< max |ξ_b − ξ_a| over |dx|, |dy| ≤ 3
    double rms_ratio = 1.0;          ///< rms_b / rms_a
    double median_offset = 0.0;      ///< median_b − median_a of the sky pixels
    /// Two-sample KS of the decimated sky pixels, each about its own median (the noise; a
    /// constant left by background subtraction is not).
    double ks_d = 0.0, ks_p = 1.0;
    /// Percentiles 1, 5, 95 and 99 of b's sky over a's (each rms × its marginal at the
    /// percentile's z); NaN where either record lacks a marginal.
    std::array<double, 4> percentile_ratio{};
};
/// The sky value at percentile `percent` (1, 5, 95 or 99): rms × T(z); NaN without a marginal.
double sky_percentile(const NoiseRecord& sky, int percent);
/// Errors when a record lacks quantiles.
SkyComparison compare_sky(const NoiseRecord& a, const NoiseRecord& b);

/// A markdown table of skies against the first (the reference): rms, MAD σ, rms/MAD σ,
/// ξ at lags (1,0) (0,1) (1,1) (2,0) (2,2) (3,0) (3,3), the largest |Δξ| within 3 pixels,
/// the rms ratio, the 1st, 5th, 95th and 99th percentiles' ratios, the offset of the medians
/// over the reference rms, and the KS D and p of the pixel histograms about their medians.
void write_sky_table(std::ostream& out, const std::vector<std::string>& names,
                     const std::vector<NoiseRecord>& skies);

}  // namespace shapesim
