// Painting objects into an image as a telescope records them (paper §4.3, DESIGN §3, §6):
// lensing, PSF convolution in shapelet space, exact pixel integration into only the pixels an
// object can reach, and noise — every step deterministic and tile-invariant.
//
// Per object (prepare_object):
//   galaxy  its record's model (rescaled to the field's pixel scale if the record's differs)
//           → lensed by (g1, g2, κ) about its centre (transform.hpp lens(), projected to the
//           order that meets `lensing_tolerance`) → convolved with the galaxy kernel (the PSF,
//           or the difference kernel new ⊘ old when the models already hold the old PSF; none
//           when they hold the new one) → Cartesian.
//   star    the star PSF (unit flux) × flux at the star's position.
// Its stamp: the square |x − x_c|, |y − y_c| < R with R the smallest radius whose rigorous
// bound on any pixel outside it is ≤ the threshold (stamp_radius()): `truncation` × the noise
// rms, or × the model's central value for a noise-free image. An object whose bound is below
// the threshold everywhere is not drawn at all.
//
// Tiles: the image is a window of the field (pixels x0…x1, y0…y1). Each object's stamp is
// always rendered whole (the same matrix products whatever the window) and its overlap with
// the window added, objects in input order: a tile's pixels equal the whole image's bit for
// bit. Noise is keyed by the field pixel (pixel_noise.hpp: WhiteNoise, PhotonNoise), so it is
// tile-invariant too. Threads split the window into bands of rows; each band adds the same
// objects in the same order, so the result does not depend on the thread count.
//
// Noise (add_noise):
//   - photon noise of the objects (and of the sky level, when given): Poisson counts at
//     `gain` electrons per image unit, N/gain with N ~ Poisson(λ), λ = (signal + sky)·gain,
//     wherever its variance (signal + sky)/gain is ≥ `photon_tolerance` × the background's
//     (a pixel left out has its variance low by less than that fraction);
//   - a Gaussian background of rms `noise_rms`: white noise convolved with `noise_kernel`,
//     the kernel of the real sky's measured 2-D correlation (noise.hpp; Σk² = 1, so the
//     per-pixel variance is kept), or without one the drizzle-like 3×3 kernel
//     [e, 1, e]⊗[e, 1, e] whose 4×4 block sums have the correlated-noise factor F
//     (shapesim-detect's `noise_correlation`). Each output pixel sums the same white values
//     in the same order whatever the band or tile: bit-identical across threads and tiles.
#pragma once

#include "shapesim/convolve.hpp"
#include "shapesim/geometry.hpp"
#include "shapesim/model.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/noise.hpp"
#include "shapesim/pixel_noise.hpp"
#include "shapesim/records.hpp"
#include "shapesim/render.hpp"
#include "shapesim/sample.hpp"
#include "shapesim/transform.hpp"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace shapesim {

struct SceneOptions {
    double truncation = 1e-3;   ///< stamp edge: left-out pixels ≤ this × noise rms (or × peak)
    double noise_rms = 0.0;     ///< Gaussian background rms, image units (0: none)
    double noise_correlation = 1.0;  ///< F of the background (1: white; drizzle-like 3×3)
    /// The background's measured correlation (noise.hpp); when set, noise_correlation is unused.
    std::optional<NoiseKernel> noise_kernel;
    /// The background's σ varies over the field as noise_rms × this (whole-field rows ×
    /// columns; from a real field's weight map, noise_scale_from_weight): drizzled depth is
    /// not uniform, and a stationary sky lacks the real one's heavier-tailed histogram.
    std::optional<ImageArray> noise_scale;
    double gain = 0.0;          ///< electrons per image unit for photon noise (0: none)
    double sky = 0.0;           ///< sky level added, image units per pixel
    /// Photon noise is drawn where its variance s/gain is at least this fraction of the
    /// background variance (everywhere when there is no background).
    double photon_tolerance = 1e-3;
    bool noise_free = false;    ///< no noise at all (the truncation then follows the peak)
    /// A galaxy's pixels below zero are set to zero: light is never negative, and a truncated
    /// or noisy shapelet series rings (holes, dipoles). Off: the exact series (the paper's).
    bool clip_negative = false;
    std::uint64_t seed = 0;
    std::optional<Lensing> lensing;
    double lensing_tolerance = 1e-8;  ///< relative truncation of the lensed projection
    int threads = 1;
    void validate() const;
};

/// What the galaxies and stars are convolved with. Models in field pixels, unit flux,
/// centred on their basis centre. Galaxies whose record says "frame": "intrinsic" (fitted
/// through their own image's PSF) are convolved with `star`, the PSF itself.
struct SceneKernels {
    std::optional<CartesianModel> galaxy;  ///< none: galaxies drawn as they are
    std::optional<CartesianModel> star;    ///< the PSF stars are drawn as (required for stars)
};

/// One object ready to paint.
struct PreparedObject {
    std::string id, kind;
    CartesianModel model;     ///< final model, centre in field FITS pixels
    PixelWindow window;       ///< its stamp, 0-based field columns/rows (may overhang)
    double radius = 0.0;      ///< R, pixels
    double flux = 0.0;        ///< true flux in the image (after lensing)
    std::optional<Moments> intrinsic;  ///< moments of the lensed galaxy before the PSF
    double lensing_error = 0.0;        ///< relative truncation of the lensed projection
    bool drawn = true;        ///< false: below the threshold everywhere
    std::size_t index = 0;    ///< the caller's bookkeeping (e.g. the input record's)
};

/// The smallest R (pixels) such that every pixel lying wholly outside the square of half-side
/// R about the model centre has |value| ≤ `threshold`, from |φ_n(u)| ≤ 1.0865 π^{−1/4} and the
/// monotone tails of φ_n beyond √(2n+1). 0 when the whole model is below it.
double stamp_radius(const CartesianModel& model, double threshold);

/// The noise_scale of a weight map (inverse variance): s = 1/√(w ⟨1/w⟩) over its good pixels
/// (w > 0 and finite), so ⟨s²⟩ = 1 and the mean variance stays noise_rms²; 1 on bad pixels.
/// Error when no pixel is good.
ImageArray noise_scale_from_weight(const ImageArray& weight);

/// The noise seed of band `band` of a multi-band run: the run seed mixed with the band's
/// name (fnv1a_64), so each band draws its own realisation from one --seed (a one-band run
/// uses the seed itself).
std::uint64_t band_seed(std::uint64_t seed, const std::string& band);

/// Widest noise kernel add_noise draws (its margin stream's keys).
constexpr int max_noise_kernel_radius = int(WhiteNoise::margin);

/// The scene's truncation threshold for a model: truncation × noise rms, or × the model's
/// value at its centre (one pixel's worth) when the image is noise-free or noiseless.
double truncation_threshold(const CartesianModel& model, const SceneOptions& options);

/// Prepare one object record (x, y in field FITS pixels required).
PreparedObject prepare_object(const ObjectRecord& record, double field_pixel_scale,
                              const SceneKernels& kernels, const SceneOptions& options,
                              ConvolveWorkspace* workspace = nullptr);

/// Every record prepared (on options.threads threads), keeping those drawn whose stamps reach
/// `window`, in input order; each one's `index` is its record's. Error naming the first object
/// (in input order) that failed.
std::vector<PreparedObject> prepare_scene(const std::vector<ObjectRecord>& records,
                                          double field_pixel_scale, const SceneKernels& kernels,
                                          const SceneOptions& options, const Tile& window);

/// What clip_negative removed from one galaxy's stamp (whole, wherever the window is).
struct ClippedLight {
    double flux = 0.0;     ///< the negative light set to zero (≥ 0, image units)
    double deepest = 0.0;  ///< its most negative pixel (≤ 0)
};

/// The noise-free image of `window` (field pixels) holding every prepared object. With
/// clip_negative and `clipped`, (*clipped)[i] says what object i lost (its whole stamp).
ImageArray paint(const std::vector<PreparedObject>& objects, const Tile& window,
                 const SceneOptions& options, std::vector<ClippedLight>* clipped = nullptr);

/// Add the noise of `options` to `image` — on entry the noise-free image, whose signal the
/// photon noise follows — the window `window` of a field `field_nx` pixels wide (pixel keys).
void add_noise(ImageArray& image, const Tile& window, long field_nx, const SceneOptions& options);

}  // namespace shapesim
