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
//     With `noise_marginal` (a measured sky's), each deviate z is then T(z): the real sky's
//     pixel histogram, its heavier tails included.
//   - then, with `saturation`, every pixel above it is set to it (a full well: flat-topped
//     bright stars, as shapesim-detect flags them from the header's SATURATE).
//
// A render end to end (shapesim-render is its options around these): read_objects() places
// the records through the field's WCS, read_scene_kernels() reads the PSF records,
// render_field() draws the window, truth_records() lists the objects centred in it once over
// a grid of tiles, scene_image_spec() writes how the image was made into its header.
#pragma once

#include "shapesim/convolve.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/geometry.hpp"
#include "shapesim/model.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/noise.hpp"
#include "shapesim/pixel_noise.hpp"
#include "shapesim/psf_field.hpp"
#include "shapesim/records.hpp"
#include "shapesim/render.hpp"
#include "shapesim/transform.hpp"

#include <cstdint>
#include <functional>
#include <iosfwd>
#include <memory>
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
    /// The background's measured pixel distribution (noise.hpp SkyMarginal): each correlated
    /// deviate z becomes T(z). Empty: Gaussian.
    SkyMarginal noise_marginal;
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
    /// A detector's full well, image units: every pixel above it, sky and noise included, is
    /// set to it (0: none; a noise-free image is never saturated). The header's SATURATE.
    double saturation = 0.0;
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
    std::string galaxy_note = "none";      ///< `galaxy` in words (the image's GALKERN card)
    /// A PSF varying across the field (psf_field.hpp): when set, each star is drawn as, and
    /// each galaxy convolved with, the PSF at its own position; `star` and `galaxy` unused.
    std::shared_ptr<const PsfField> field;
    bool has_psf() const { return star.has_value() || field != nullptr; }
};

/// The kernels of a PSF varying across the field (galaxies convolved with it, as stars are).
SceneKernels field_kernels(PsfField field);

/// The kernels of an image whose PSF is `psf` (unit flux, field pixels), the galaxy models
/// already holding `models_psf` (none: no PSF): stars are drawn as `psf`; galaxies convolved
/// with it, with nothing when `models_psf` is the same model, else with the difference kernel
/// psf ⊘ models_psf (convolve.hpp) of order `difference_order` (< 0: the PSF's n_max).
SceneKernels scene_kernels(const ShapeletModel& psf,
                           const std::optional<ShapeletModel>& models_psf = std::nullopt,
                           int difference_order = -1);

/// The kernels of the PSF record at `psf_path` and, when not empty, the models' PSF record at
/// `models_psf_path` (read_psf_model() at the field's `pixel_scale`); none without a PSF.
SceneKernels read_scene_kernels(const std::string& psf_path, const std::string& models_psf_path,
                                double pixel_scale, int difference_order);

/// Take the background from the real sky's measured noise (noise.hpp): its rms, its F (at
/// least 1) and the kernel that draws its correlation.
void use_sky_noise(SceneOptions& options, const NoiseRecord& noise);

/// The noise_scale of the weight map at `path` (noise_scale_from_weight), which must be the
/// field's size, `field_nx` × `field_ny`; Error naming the file otherwise.
ImageArray read_noise_scale(const std::string& path, long field_nx, long field_ny);

/// One object ready to paint.
/// What a truth record says of a shape: its ellipticity ε and rms radius (moments.hpp; NaN
/// where undefined), kept instead of all its moments (a million objects' worth).
struct ShapeSummary {
    Complex epsilon;
    double rms_radius = 0.0;
    static ShapeSummary of(const Moments& m) { return {m.epsilon, m.rms_radius}; }
};

struct PreparedObject {
    std::string id, kind;
    CartesianModel model;     ///< final model, centre in field FITS pixels
    PixelWindow window;       ///< its stamp, 0-based field columns/rows (may overhang)
    double radius = 0.0;      ///< R, pixels
    double flux = 0.0;        ///< true flux in the image (after lensing)
    std::optional<ShapeSummary> intrinsic;  ///< the lensed galaxy before the PSF
    std::optional<ShapeSummary> psf;        ///< the PSF it was drawn with, when it varies
    std::optional<Complex> unlensed_epsilon;  ///< its ellipticity before lensing (NaN: undefined)
    std::optional<Lensing> lensing;           ///< the lensing applied to it
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

/// How read_objects() places and checks the objects.
struct ObjectPlacement {
    bool have_psf = false;        ///< --psf given (a point source is drawn as the PSF)
    bool galaxy_psf_known = false;///< --galaxy-psf given: what observed-frame models hold
    /// false: an object whose own x, y (the field shapesim-sample drew it for) differ from
    /// its ra, dec through `wcs` by more than `max_shift` pixels is an error (the field was
    /// given differently); true: placed by ra, dec alone.
    bool by_sky = false;
    double max_shift = 0.01;
};

/// The extra fields of an object record a render reads: its frame (observed or intrinsic), the
/// PSF an intrinsic star was seen through (psf_beta), and the ring it belongs to (the truth).
inline constexpr const char* render_record_keys[] = {"frame", "psf_beta", "ring"};

/// The object records at `path` (JSON lines; "-": stdin), read on `threads` threads and placed
/// on the field: each as it is in band `band` (empty: as written), x, y from its ra, dec
/// through `wcs`. Error at the file, line and field of the first bad record; of the first
/// star without a PSF; of the first object drawn for another field (ObjectPlacement); of the
/// first observed-frame galaxy ("frame": "observed": it holds its field's PSF) given a PSF
/// without --galaxy-psf, which would convolve it twice. Each record keeps only what a render
/// reads (render_record_keys of its extra fields; no flags, parent or other bands): a million
/// sampled objects carry about 0.7 GB of provenance (parents, weights, rotation) no pixel or
/// truth needs.
std::vector<ObjectRecord> read_objects(const std::string& path, const Wcs& wcs,
                                       const std::string& band, const ObjectPlacement& placement,
                                       int threads);

/// Prepare one object record (x, y in field FITS pixels required).
PreparedObject prepare_object(const ObjectRecord& record, double field_pixel_scale,
                              const SceneKernels& kernels, const SceneOptions& options,
                              ConvolveWorkspace* workspace = nullptr);

/// Whether a stamp (0-based field columns and rows) shares a pixel with `window` (FITS pixels,
/// inclusive): the overlap paint() adds.
bool stamp_reaches(const PixelWindow& stamp, const Tile& window);

/// Every record prepared (on options.threads threads), keeping those drawn whose stamps reach
/// `window`, in input order; each one's `index` is its record's. Error naming the first object
/// (in input order) that failed.
std::vector<PreparedObject> prepare_scene(const std::vector<ObjectRecord>& records,
                                          double field_pixel_scale, const SceneKernels& kernels,
                                          const SceneOptions& options, const Tile& window);

/// Leave of `record` only what truth_record reads (its id, kind, place, flux, magnitude and
/// ring): its shape, bands and other extra fields are released.
void keep_for_truth(ObjectRecord& record);
/// Ask prepare_scene / prepare_field to keep_for_truth() each record once it is prepared, so
/// a field's shapes are not held twice (a million objects' worth).
struct ReleaseShapes {};
std::vector<PreparedObject> prepare_scene(std::vector<ObjectRecord>& records,
                                          double field_pixel_scale, const SceneKernels& kernels,
                                          const SceneOptions& options, const Tile& window,
                                          ReleaseShapes);

/// What clip_negative removed from one galaxy's stamp (whole, wherever the window is).
struct ClippedLight {
    double flux = 0.0;     ///< the negative light set to zero (≥ 0, image units)
    double deepest = 0.0;  ///< its most negative pixel (≤ 0)
};

/// The noise-free image of `window` (field pixels) holding every prepared object. With
/// clip_negative and `clipped`, (*clipped)[i] says what object i lost (its whole stamp).
ImageArray paint(const std::vector<PreparedObject>& objects, const Tile& window,
                 const SceneOptions& options, std::vector<ClippedLight>* clipped = nullptr);
/// paint() into `image`, reused when it has the window's size (reallocated otherwise).
void paint_into(ImageArray& image, const std::vector<PreparedObject>& objects, const Tile& window,
                const SceneOptions& options, std::vector<ClippedLight>* clipped = nullptr);

/// Add the noise of `options` to `image` — on entry the noise-free image, whose signal the
/// photon noise follows — the window `window` of a field `field_nx` pixels wide (pixel keys).
void add_noise(ImageArray& image, const Tile& window, long field_nx, const SceneOptions& options);

/// A rendered window of a field: the objects drawn into it, what clipping took from each,
/// the noisy image, and the time each step took.
struct RenderedScene {
    FieldGeometry field;                  ///< the field the window is of
    Tile window;                          ///< its pixels drawn (FITS, inclusive)
    std::vector<PreparedObject> objects;  ///< prepare_scene()'s, in input order
    std::vector<ClippedLight> clipped;    ///< clipped[i]: what objects[i] lost (paint())
    ImageArray image;                     ///< the window's pixels, noise included
    /// Seconds each step took; drawn in strips, paint and noise are summed over the threads
    /// and sink_seconds is the time the sink (writing) took, overlapping the others.
    double prepare_seconds = 0.0, paint_seconds = 0.0, noise_seconds = 0.0, sink_seconds = 0.0;
};

/// prepare_scene() for `window` of `field`: the objects drawn, no pixels yet (clipped all 0).
/// An object's failure is an Error at `source`, the records' file.
RenderedScene prepare_field(const std::vector<ObjectRecord>& records, const FieldGeometry& field,
                            const SceneKernels& kernels, const SceneOptions& options,
                            const Tile& window, const std::string& source);
/// The same, each record kept for the truth only once prepared (ReleaseShapes).
RenderedScene prepare_field(std::vector<ObjectRecord>& records, const FieldGeometry& field,
                            const SceneKernels& kernels, const SceneOptions& options,
                            const Tile& window, const std::string& source, ReleaseShapes);

/// paint() and add_noise() for a prepared scene, the whole window at once into scene.image.
void draw_whole(RenderedScene& scene, const SceneOptions& options);

/// Rows first … first + strip.rows() − 1 (0-based, of the window) of the finished image.
using StripSink = std::function<void(long first, const ImageArray& strip)>;

/// The rows of a strip of about 1 M pixels of a window `width` pixels wide (at least 64).
long default_strip_rows(long width);

/// paint() and add_noise() for a prepared scene, `strip_rows` rows at a time, top to bottom,
/// each strip handed to `sink` in order: the same bits as render_field's image (every pixel
/// is a function of its field pixel), holding only the strips in flight (threads + 1), not
/// the window. The threads share the strips; the sink runs on one thread at a time while the
/// others draw. Fills scene.clipped and the times; scene.image stays empty.
void draw_in_strips(RenderedScene& scene, const SceneOptions& options, long strip_rows,
                    const StripSink& sink);

/// The window `window` of the field `field` holding `records` (x, y set): prepare_field(),
/// paint(), add_noise(), the whole window in memory.
RenderedScene render_field(const std::vector<ObjectRecord>& records, const FieldGeometry& field,
                           const SceneKernels& kernels, const SceneOptions& options,
                           const Tile& window, const std::string& source);

/// The truth of object `object` drawn from `record` (what paint() drew, with the negative
/// light `clipped` took away added back: flux, and mag moved by it).
TruthRecord truth_record(const PreparedObject& object, const ObjectRecord& record,
                         const ClippedLight& clipped);

/// The truths of the objects of `scene` centred in its window (Tile::owns), in input order:
/// the truths of a grid of tiles hold every object once (stamps reaching in from outside are
/// drawn, not listed). `records` are those the scene was rendered from.
std::vector<TruthRecord> truth_records(const RenderedScene& scene,
                                       const std::vector<ObjectRecord>& records);

/// Write truth_records() as JSON lines (shapesim.truth/1) to `out`, named `name` in errors.
void write_truth_records(std::ostream& out, const std::string& name, const RenderedScene& scene,
                         const std::vector<ObjectRecord>& records);

/// The objects' own zero point, mag + 2.5 log₁₀ flux, when every object with a mag and a
/// positive flux agrees on it to 1e-6 (nullopt when they disagree or none has both): a
/// simulation measured without --zero-point gets its true magnitudes.
std::optional<double> objects_zero_point(const std::vector<ObjectRecord>& records);

/// What clip_negative took from a scene's galaxies, over all of them.
struct ClippedSummary {
    long galaxies = 0;     ///< galaxies that lost light
    double largest = 0.0;  ///< the largest fraction of a galaxy's |flux| lost
    double deepest = 0.0;  ///< the most negative pixel (≤ 0)
};
ClippedSummary summarise_clipped(const RenderedScene& scene);

/// What a rendered image's header names besides SceneOptions: the run's seed (a band's noise
/// seed is drawn from it), the PSF record ("none"), the background's correlation in words, the
/// band drawn (empty: none).
struct SceneLabels {
    std::uint64_t seed = 0;
    std::string psf = "none", noise, band;
    double exposure_time = 0.0;  ///< EXPTIME, seconds (0: not written)
    std::string bunit;           ///< BUNIT (empty: the field's)
};

/// The image HDU of a rendered scene: EXTNAME SCI, `bitpix`, the field's BUNIT and its WCS moved
/// to the window, and cards saying how it was made (seed, truncation, noise, gain, sky,
/// lensing, PSF, galaxy kernel, window, field size, band, objects drawn) and, when they agree
/// (objects_zero_point()), the objects' zero point MAGZERO (and PHOTZP, its other common
/// name) to 1e-6; EXPTIME and BUNIT from `labels` when set.
FitsImageSpec scene_image_spec(const RenderedScene& scene, const std::vector<ObjectRecord>& records,
                               const SceneOptions& options, const SceneKernels& kernels,
                               const SceneLabels& labels, int bitpix);

}  // namespace shapesim
