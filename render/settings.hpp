// shapesim-render's settings: what its options fill in (render/main.cpp declares them, so
// --help reads in one place), the checks between them, and the SceneOptions they make — the
// noise (--noise-like, --noise-model, --noise-weight), gain × exposure, the band's seed.
#pragma once

#include "app/field_options.hpp"
#include "app/log.hpp"
#include "app/options.hpp"
#include "shapesim/scene.hpp"

#include <string>
#include <vector>

namespace shapesim::app {

/// The line saying what clip_negative took (`clipped`, summarise_clipped()): how many galaxies,
/// the largest fraction of a galaxy's flux, the deepest pixel and, when `noise_rms` > 0, that
/// pixel in σ. Empty when no galaxy lost light (nothing worth saying).
std::string clipped_note(const ClippedSummary& clipped, double noise_rms);

/// The stage line of a rendered window: objects drawn of `records`, the window's size, the
/// galaxy kernel in words, and the seconds of each step (`read_seconds` the caller's; prepare,
/// paint, noise and write the scene's: drawn in strips, paint and noise are summed over the
/// threads). Timings go to stderr, never into outputs.
std::string render_summary(const RenderedScene& scene, std::size_t records, const Tile& window,
                           const SceneKernels& kernels, double read_seconds);

/// SceneLabels::noise (the NOISEMOD card): the background's correlation in words — the measured
/// noise record at `noise_model` (use_sky_noise), else the drizzle-like 3×3 kernel (NOISECOR) —
/// and whether a weight map scales it (`weighted`, read_noise_scale).
std::string noise_label(const std::string& noise_model, bool weighted);

struct RenderSettings {
    std::string input = "-", psf, galaxy_psf, truth, noise_like, noise_model, noise_weight, band;
    std::string psf_analytic;   ///< --psf-analytic SPEC (analytic_psf.hpp)
    std::string psf_field;      ///< --psf-field FILE: PSFEx's model (psf_field.hpp)
    bool place_by_sky = false;  ///< --place-by-sky: no check of the objects' own x, y
    FieldOptions field;
    std::vector<double> shear;
    double kappa = 0.0, exposure = 1.0;
    double exptime = 0.0;  ///< --exptime (EXPTIME; 0: --exposure when given, else none)
    std::string bunit;     ///< --bunit (BUNIT; empty: the field's)
    int bitpix = -32, difference_order = -1;
    bool keep_negative = false;
    bool gaussian_noise = false;  ///< --gaussian-noise: the noise record's marginal unused
    SceneOptions scene;

    /// Check the options against each other before any work (po::error naming the rule): an
    /// output, --bitpix, writable outputs, --galaxy-psf with --psf, one source of the noise,
    /// --shear as G1 G2 with |g| < 1; then set the scene's lensing.
    void check(const ProgramOptions& options);
    /// Finish `scene` for `field`: the noise from the records, the sky's noise record and the
    /// weight map; gain × exposure, the (band's) seed, threads, clipping; validated.
    void finish_scene(const ProgramOptions& options, const FieldGeometry& field, const Log& log);
    /// The image header's labels (SceneLabels).
    SceneLabels labels(const ProgramOptions& options) const;
    /// Draw the prepared scene (`scene` options) and write the image (-o, with the run's
    /// provenance) and --truth, each atomically: both files appear only when both were
    /// written. The image is drawn and written in strips (draw_in_strips), unless BITPIX −32
    /// cannot hold a pixel: then it is drawn whole and written as −64, so nothing is lost.
    void draw_and_write(const ProgramOptions& options, RenderedScene& rendered,
                        const std::vector<ObjectRecord>& records,
                        const SceneKernels& kernels) const;
};

}  // namespace shapesim::app
