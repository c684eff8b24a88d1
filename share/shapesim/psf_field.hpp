// A PSF that varies across the field: PSFEx's model read as it is (Bertin 2011), and its
// shapelet form. PSFEx: P(x, y) = Σ_k x̃^i ỹ^j B_k, x̃ = (x − POLZERO1)/POLSCAL1, ỹ likewise,
// i + j ≤ POLDEG1. The shapelet form fits every B_k with one β, n_max and centre as the
// pixel-integrated basis, so it is the PSF before the pixel, and exactly the fit of PSFEx's
// image at every (x, y).
// Derivation: docs/algorithms.md#a-psf-across-the-field
#pragma once

#include "shapesim/image.hpp"
#include "shapesim/model.hpp"

#include <string>
#include <vector>

namespace shapesim {

/// How the PSF varies: PSFEx's polynomial in x̃, ỹ (the file comment).
struct PsfVariation {
    int degree = 0;                       ///< POLDEG1 (0: one PSF for the field)
    double x_zero = 0, y_zero = 0;        ///< POLZERO1, POLZERO2 (FITS pixels)
    double x_scale = 1, y_scale = 1;      ///< POLSCAL1, POLSCAL2 (pixels)
    /// The K monomials x̃^i ỹ^j at (x, y), in PSFEx's order.
    std::vector<double> terms(double x, double y) const;
    /// Whether (x, y) lies within the range of the stars the polynomial was fitted to,
    /// |x̃|, |ỹ| ≤ ½ (always, for degree 0): beyond it the polynomial is extrapolated.
    bool within_stars(double x, double y) const;
};

/// A PSFEx model as its file holds it (one context group of two image coordinates).
struct PsfexModel {
    PsfVariation variation;
    double sampling = 1;                  ///< PSF_SAMP: image pixels per sample
    std::string x_name, y_name;           ///< POLNAME1, POLNAME2 (X_IMAGE, Y_IMAGE, …)
    std::vector<ImageArray> components;   ///< B_k, rows along y, one per term
};

/// The PSFEx model in the PSF_DATA table of `path` (psfex's .psf). Error naming the file and
/// keyword when it is not one: no PSF_DATA, a context that is not two image coordinates in one
/// group, PSFAXIS3 not (d+1)(d+2)/2, a sampling or scale not > 0, a stamp over 1024² samples or
/// of even size, values not finite.
PsfexModel read_psfex(const std::string& path);

/// PSFEx's own PSF image at (x, y): Σ_k terms_k B_k, its samples (not normalised).
ImageArray psfex_image(const PsfexModel& model, double x, double y);

struct PsfFieldOptions {
    int n_max_min = 4, n_max_cap = 20;
    double residual_target = 0.005;       ///< stop once the worst |residual| ≤ this × peak
    double min_resolution_pixels = 0.5;   ///< β/√(n_max+1) ≥ this (image pixels)
    double beta_tolerance = 1e-3;         ///< final bracket in ln β
};

/// The shapelet form of a PSFEx model (docs/algorithms.md), in the image's pixels.
struct PsfField {
    PsfVariation variation;               ///< PSFEx's
    int n_max = 0;
    double beta_pix = 1;
    std::vector<Eigen::MatrixXd> b;       ///< Cartesian coefficients of each term
    std::vector<double> flux;             ///< each term's flux
    double max_residual_fraction = 0;     ///< worst |PSFEx − model| / peak over the 3 × 3 places
    bool reached_target = false;
    /// The PSF at (x, y), unit flux, centred at (0, 0). Error when its flux there is not > 0
    /// (a polynomial taken far beyond the stars it was fitted to).
    CartesianModel at(double x, double y) const;
};

PsfField fit_psf_field(const PsfexModel& model, const PsfFieldOptions& options = {});

/// read_psfex() then fit_psf_field(), with Errors naming `path`.
PsfField read_psf_field(const std::string& path, const PsfFieldOptions& options = {});

}  // namespace shapesim
