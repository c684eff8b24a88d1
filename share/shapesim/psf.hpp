// PSF mode: a shapelet model of a PSF image (DESIGN §3, paper §2.3). The image is noise-free,
// so the fit is plain least squares (lsq.hpp) and "good" means max |residual| ≤
// residual_target · peak, not χ²_r: at each n_max the centre moves until the model's own
// centroid sits on it and β minimises the residual over ln β; n_max rises until the target is
// met. The model has unit flux, its centre in the stamp's FITS coordinates, β in its pixels.
// Derivation: docs/algorithms.md#psf-images
#pragma once

#include "shapesim/image.hpp"
#include "shapesim/model.hpp"
#include "shapesim/records.hpp"

#include <limits>
#include <string>
#include <optional>
#include <string>
#include <vector>

namespace shapesim {

struct PsfFitOptions {
    int n_max_min = 0;               ///< first n_max tried
    int n_max_cap = 20;              ///< last n_max tried
    double residual_target = 0.005;  ///< stop once max |residual| ≤ this × peak
    double beta_tolerance = 1e-4;    ///< final bracket width in ln β
    int beta_grid = 16;              ///< ln β scan points before refinement (≥ 3)
    double min_resolution_pixels = 0.5;  ///< β/√(n_max+1) ≥ this (pixels)
    int centre_iterations = 5;       ///< re-centrings on the model's centroid, at most
    double centre_tolerance = 1e-4;  ///< pixels; stop re-centring below this move
};

/// The best fit at one n_max.
struct PsfFitStep {
    int n_max = 0;
    double beta_pix = 0.0;
    double x = 0.0, y = 0.0;              ///< basis centre, stamp FITS pixels
    double max_residual_fraction = 0.0;   ///< max |residual| / peak
    double rms_residual_fraction = 0.0;   ///< rms residual over the stamp / peak
    double centroid_offset = 0.0;         ///< |model centroid − basis centre|, pixels
    int fits = 0;                         ///< least-squares fits spent on this n_max
};

struct PsfModel {
    ShapeletModel model;                  ///< unit flux; centre in stamp FITS pixels; β in pixels
    int n_max = 0;
    double max_residual_fraction = 0.0;   ///< max |data − model| / max data
    double rms_residual_fraction = 0.0;   ///< rms (data − model) over the stamp / max data
    bool reached_target = false;          ///< max_residual_fraction ≤ residual_target
    ImageArray image;                     ///< the unit-flux model, pixel-integrated on the stamp
    ImageArray residual;                  ///< data / F − image, F the fitted model's flux
    double peak = 0.0;                    ///< max of data / F
    double data_flux = 0.0;               ///< Σ data over the stamp (input units)
    double model_flux = 0.0;              ///< F: flux of the fit before normalisation (input units)
    double beyond_reach_flux_fraction = 0.0;  ///< Σ data at r > β√(n+1) / Σ data
    double beyond_reach_max_residual_fraction = 0.0;  ///< max |residual| there / peak
    /// psf_from_oversampled only: 1 − (flux in the stamp)/(flux of the box-convolved fine
    /// image); NaN otherwise.
    double flux_outside_stamp = std::numeric_limits<double>::quiet_NaN();
    std::vector<PsfFitStep> steps;        ///< every n_max tried, in order
};

/// Fit a shapelet model to a noise-free PSF image already at the target pixel scale
/// (docs/algorithms.md#psf-images). Error when the image is empty, not finite, has max ≤ 0 or
/// Σ ≤ 0, the options are inconsistent, or no n_max admits a β (stamp too small).
PsfModel fit_psf_image(const ImageArray& psf_pixels_at_target_scale,
                       const PsfFitOptions& options = {});

/// Median of the outermost ring of pixels of `image` (0 when it is empty): the sky level of a
/// star's cutout.
double border_median(const ImageArray& image);

/// An oversampled PSF image (pixels `fine_scale` wide, arcsec) to a PSF model at
/// `target_scale` (arcsec per pixel): convolve with each box of `boxes_arcsec` in turn (e.g.
/// the detector pixel and the drizzle drop, which TinyTim's subsampled PSFs lack; resample.hpp
/// box_convolve), integrate over the target pixels into a stamp_pixels² stamp (odd) whose
/// centre pixel holds the flux centroid (resample_pixel_integrated), and fit_psf_image it.
/// Sets flux_outside_stamp. Error when the scales are not > 0, a box is not > 0, the stamp size
/// is even or < 3, or the fine image is unusable.
PsfModel psf_from_oversampled(const ImageArray& fine, double fine_scale, double target_scale,
                              const std::vector<double>& boxes_arcsec, int stamp_pixels,
                              const PsfFitOptions& options = {});

/// An oversampled PSF image as read from a file.
struct PsfImage {
    ImageArray pixels;         ///< sky removed
    double pixel_scale = 0.0;  ///< arcsec per pixel
    double sky = 0.0;          ///< the level removed: border_median of the file's pixels
};
/// The first image of `path` (cfitsio syntax allowed) at `pixel_scale` when given, else at
/// its header's PIXSCALE (TinyTim's keyword), else its WCS (a star cut from a field); its sky
/// (border_median) subtracted. Error naming the file when no pixel scale is there.
PsfImage read_psf_image(const std::string& path, std::optional<double> pixel_scale);

/// The PSF shapelet record of `path` (its first line, e.g. shapesim-decompose's PSF mode) as
/// a model in pixels of `pixel_scale` arcsec (β rescaled, flux kept), normalised to unit flux
/// and centred at (0, 0). Error naming the file and line when there is no record or its flux
/// is not positive.
ShapeletModel read_psf_model(const std::string& path, double pixel_scale);

/// `fine` (at `fine_scale` arcsec per pixel) convolved with square boxes `boxes_arcsec` wide,
/// in turn (box_convolve): the detector pixel and a drizzle drop a subsampled PSF lacks.
/// Error for a width that is not finite and > 0.
ImageArray convolve_boxes(const ImageArray& fine, double fine_scale,
                          const std::vector<double>& boxes_arcsec);

/// A `shapesim.shapelet/1` record of the PSF model at `pixel_scale` (arcsec per pixel), for
/// shapesim-render: flux 1; flags "converged" when the target was reached, else
/// "residual_above_target"; extra fields psf_max_residual, psf_rms_residual and, when known,
/// psf_flux_outside_stamp.
ShapeletRecord psf_record(const PsfModel& psf, double pixel_scale, std::string id);

}  // namespace shapesim
