// Shared helpers for the unit tests and benchmarks (the one home for them): where the
// fixtures are, reading the GalSim reference models, stamps and exact convolutions, an
// independent quadrature (composite Gauss–Legendre) for brute force, and random models.
#pragma once

#include "shapesim/convolve.hpp"
#include "shapesim/image.hpp"
#include "shapesim/model.hpp"
#include "shapesim/morphology.hpp"
#include "shapesim/records.hpp"

#include <cstdint>
#include <functional>
#include <random>
#include <string>
#include <vector>

namespace shapesim::test {

/// The repository the test binary was built from: $SHAPESIM_SOURCE_DIR when set, else three
/// folders up from the binary itself (<root>/build*/tests/<binary>, through /proc/self/exe).
/// No absolute path is compiled in, so a compiler cache serves every clone alike.
const std::string& source_dir();

/// Folder of the exact reference fixtures: tests/data/reference in the repository, else
/// $SHAPESIM_DATA/reference. (The readers below throw, naming it, when files are missing.)
std::string reference_dir();

/// One model of reference/models.jsonl with its id and stamp size.
struct ReferenceModel {
    std::string id;
    ShapeletModel model;  ///< in pixel units (ShapeletRecord::to_model)
    double flux = 0.0;    ///< the record's `flux` field, as written with the fixtures
    int nx = 0, ny = 0;
    ImageArray stamp;  ///< the GalSim-rendered stamp from stamps.fits
};
/// All 24 reference models with their stamps (read once, cached).
const std::vector<ReferenceModel>& reference_models();

/// One line of reference/convolved.jsonl: galaxy ⊗ PSF, the exact result and its image.
struct ReferenceConvolution {
    ReferenceConvolutionRecord record;  ///< the line as read
    ShapeletModel galaxy;  ///< models.jsonl's `galaxy_id`, centred at (record.x, record.y)
    ShapeletModel psf, result;  ///< record.psf, record.result in pixel units
    ImageArray image;           ///< convolved.fits[record.hdu], record.ny × record.nx
};
/// All 8 reference convolutions with their images (read once, cached).
const std::vector<ReferenceConvolution>& reference_convolutions();

/// The HDU (1-based, primary = 1) of a FITS file as an image, read with cfitsio directly.
ImageArray read_fits_image(const std::string& path, int hdu);

/// n-point Gauss–Legendre nodes and weights on [−1, 1] (Newton on P_n; independent of the
/// library's Gauss–Hermite code).
void gauss_legendre(int n, std::vector<double>& nodes, std::vector<double>& weights);

/// ∫_a^b f(x) dx by composite Gauss–Legendre: `panels` panels of `order` points each.
double integrate(const std::function<double(double)>& f, double a, double b, int panels = 1,
                 int order = 20);

/// ∫ f over the unit pixel centred at (x, y) by an order × order Gauss–Legendre product rule
/// (FITS pixel (i, j), 0-based, is centred at (i + 1, j + 1)).
double integrate_pixel(const std::function<double(double, double)>& f, double x, double y,
                       int order = 10);

/// The convolution tensor against brute force: max over x in `xs`, n ≤ n_f, m ≤ n_g of
/// |Σ_l C_nml B_l(x; γ) − ∫ B_n(x′; α) B_m(x − x′; b) dx′|, the integral by the trapezoid rule
/// of step `step` on [−half_width, half_width] (spectrally accurate for these entire,
/// Gaussian-decaying integrands).
double tensor_brute_force_error(const ConvolutionTensor& c, const std::vector<double>& xs,
                                double step, double half_width);

/// h = f ∗ g against the lattice sum δ² Σ_i f(x_i) g(x − x_i) of the point-sampled models
/// (`evaluate`) on a lattice of step δ = `step`: max |h − sum| / max |h| over the points
/// (p, q)·δ off h's centre, |p| ≤ p_max and |q| ≤ q_max in strides of `stride`.
double lattice_convolution_error(const ShapeletModel& f, const ShapeletModel& g,
                                 const ShapeletModel& h, double step, int p_max, int q_max,
                                 int stride);

/// A model with normal random coefficients drawn from `engine` in packed order: galaxy-like
/// (a_00 = 1, the others ~amplitude·e^{−n/5}) when `galaxy`, else all of scale 1.
ShapeletModel random_model(std::mt19937_64& engine, int n_max, double beta_pix, double x,
                           double y, bool galaxy = true, double amplitude = 0.35);
/// The same from a fresh engine seeded with `seed` (deterministic in `seed`).
ShapeletModel random_model(int n_max, double beta_pix, double x, double y, unsigned seed,
                           bool galaxy = true, double amplitude = 0.35);

/// One object of a synthetic field, with its true properties.
struct SyntheticObject {
    double x = 0.0, y = 0.0;  ///< true centre, FITS pixels
    double flux = 0.0;        ///< true total flux, image units
    double sigma = 0.0;       ///< Gaussian σ before shear, pixels (the PSF σ for stars)
    double g1 = 0.0, g2 = 0.0;///< shear applied (GalSim reduced shear)
    bool star = false;
};
/// A synthetic deep field: elliptical Gaussian galaxies and point sources (Gaussian PSF of
/// σ `psf_sigma`), pixel-integrated by the library renderer, plus white Gaussian noise of σ
/// `noise_sigma`, all drawn from RandomStream(seed, …) so the field is deterministic.
/// Objects are placed on a jittered grid (spacing `spacing` pixels, ≥ 8 pixels from the edges),
/// galaxies with σ in [1.2, 3]·psf_sigma, |g| ≤ 0.4, and fluxes log-uniform in
/// [flux_min, flux_max]; every `star_every`-th object is a star (0: none).
struct SyntheticField {
    ImageArray image;   ///< noisy image
    ImageArray weight;  ///< 1/noise_sigma² everywhere
    std::vector<SyntheticObject> objects;
};
SyntheticField synthetic_field(int nx, int ny, double spacing, double flux_min, double flux_max,
                               double noise_sigma, std::uint64_t seed, double psf_sigma = 1.5,
                               int star_every = 0);

/// A galaxy-like random model (a_00 dominant, random_model) centred in a `side`² stamp, its
/// centroid on the basis centre (the optimiser centres on the centroid; a truth off it has no
/// finite expansion there), scaled to total `flux`.
ShapeletModel centred_galaxy(int n_max, double beta, int side, unsigned seed, double flux);
/// render_stamp(model) plus white noise σ from RandomStream(seed, id, "noise").
ImageArray noisy_stamp(const ShapeletModel& model, int side, double sigma, std::uint64_t seed,
                       std::uint64_t id);

/// Decompositions of noisy stamps of known models (decompose.hpp with default options):
/// truth n_max 2, 4, 8, 12, β = 1.15 and 1.6 × √(n+1) px, S/N 10, 100, 1000 (σ such that the
/// flux within 2β has S/N 2·snr), `seeds` models each, unit flux in a 61² stamp.
struct DecomposeGrid {
    int cases = 0;
    int max_excess = -100;   ///< largest fitted − true n_max
    int over = 0;            ///< cases with fitted n_max > truth + 2
    std::vector<double> snr; ///< per case
    std::vector<double> pull;///< (F − 1)/σ_F per case
    std::vector<double> converged_chi2r;
};
DecomposeGrid decompose_grid(int seeds);

/// Mean and rms about the mean of the values of `v` whose `key` satisfies `keep`.
struct MeanRms {
    double mean = 0.0, rms = 0.0, error = 0.0;  ///< error: rms/√n, the mean's
    std::size_t n = 0;
};
MeanRms mean_rms(const std::vector<double>& v, const std::vector<double>& key,
                 const std::function<bool(double)>& keep);

/// A morphology of 200 galaxy-like random models (random_model, amplitude 0.2), β 1–5 px at
/// 0.04″, magnitudes 22–29 (zero point 25), default λ's: with the HDF cut's n_max mix (147 of
/// 160 at 0, the rest 2–7), or `heavy`: n_max = k mod 16.
Morphology synthetic_morphology(bool heavy);

/// libsep's exact aperture sums (subpix 0, no mask, no noise) over a row-major w × h image: the
/// circle of radius r, and the ellipse of semi-axes a (at θ, counter-clockwise from x) and b,
/// about (x, y). NaN where sep refuses the aperture.
double sep_circle_sum(const std::vector<double>& data, int w, int h, double x, double y, double r);
double sep_ellipse_sum(const std::vector<double>& data, int w, int h, double x, double y,
                       double a, double b, double theta);

/// Kolmogorov–Smirnov p-value of a sample against a CDF (asymptotic distribution with
/// Stephens' small-sample correction; Press et al., Numerical Recipes §14.3).
double ks_p_value(std::vector<double> sample, const std::function<double(double)>& cdf);

/// A scratch directory under /tmp, removed with everything in it when the object goes.
class TempDir {
public:
    TempDir();
    ~TempDir();
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;
    const std::string& path() const { return path_; }

private:
    std::string path_;
};

}  // namespace shapesim::test
