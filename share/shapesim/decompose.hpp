// The shapelet decomposition of one stamp with optimised centre, β and n_max (paper §2.2,
// DESIGN §3; Massey & Refregier 2005 §5 for the constraints).
//
// For each n_max from `n_max_min` upward:
//   β: a golden-section search on ln β minimising χ²_r, within the constraints that the
//      smallest scale the data see, θ_min = β/√(n_max+1), is not below `theta_min` pixels, and
//      the largest, θ_max = β√(n_max+1), stays inside the stamp (distance from the centre to
//      the nearest stamp edge). An intrinsic model (through a PSF) is seen at √(β² + σ²)
//      (σ² half the trace of the sharpest band's PSF second moments): its own β may go below
//      the pixel, to a twentieth of the limit, so a galaxy smaller than the PSF keeps its size;
//   centre: moved to the fitted model's own centroid (closed form, moments.hpp) and the fit
//      repeated, until it moves less than `centre_tolerance` pixels;
// and n_max is chosen by the data: an order becomes the candidate when it lowers χ² below the
// current candidate's by more than the noise would take up with the extra coefficients,
// Δχ² > F²·(Δp + `order_sigmas`·√(2Δp)) (Δp more real coefficients, F the correlated-noise
// factor below), and the search stops when two orders beyond the candidate brought nothing
// significant (odd orders alone can be empty for a symmetric galaxy). The test is on χ², not
// χ²_r, so the sky a stamp includes does not decide the order (a 3a + 5 stamp stopped a faint
// galaxy at its top order, the same galaxy in a stamp grown to its real extent would stop at
// n_max 0 once χ²_r is diluted below 1 by sky), and a bright galaxy goes on while its orders
// still take up real structure. The stop says why: "chi2_target" (and the fit is converged,
// χ²_r ≤ `chi2_target` + `chi2_sigmas`·√(2/dof): at the true order χ²_r itself scatters about
// 1 by √(2/dof)), "flattened" (no more significant orders, but χ²_r above that: the noise
// model, not the order, limits the fit), "n_max_cap" (orders were still significant at the
// cap; the fit at the cap kept, converged only if its χ²_r is within the target), or
// "stamp_small" (the constraints leave no β). A fit kept with χ²_r above `bad_fit_chi2r` is a
// bad model, whatever stopped it ("bad_fit").
//
// The elliptical lowest order. Most faint galaxies stop at n_max 0: the two orders that would
// hold their ellipticity (a_{2,±2}) come with three more coefficients the noise takes up, so
// a real but faint elongation is not significant, and the model is round (the HDF's faint
// galaxies measured rms e 0.39, their round models 0.31). So where the search ends at n_max 0
// a sheared Gaussian is fitted too: the round Gaussian sheared by a reduced shear (g1, g2)
// (transform.hpp shear), expanded to n_max `elliptical_order`, its amplitude linear
// (lsq.hpp fit_shape_amplitude), (g1, g2, ln β) by Nelder–Mead; its minor-axis scale is held
// to θ_min and its major axis to the stamp as n_max 0's β is. The best fit's shear is the
// galaxy's plus the noise's (E|g|² = |g|² + tr C, C from χ²'s curvature in g): the model takes
// ĝ = g·√(1 − tr C/|g|²), so that a faint population's models are as elongated as its galaxies
// (round ones too round, best fits too elongated), and stays round where |g|² ≤ tr C;
// the record keeps its order-4 coefficients (and flags it "elliptical").
//
// Correlated noise. With per-pixel variances right but neighbouring pixels correlated, the
// residual χ² of a fit of p smooth basis functions is E χ² = N − tr(H C) ≈ N − p·F², where
// F is the correlated-noise factor (detect.hpp: rms of block sums over √Σσ²): a smooth
// function's coefficient variance is inflated by F² as the block sums are. χ²/(N − p) then
// falls below 1 before the model has taken up the galaxy (drizzled HDF: F ≈ 1.8, so a
// 15-coefficient model on 100 pixels reaches χ²_r ≈ 0.57 on pure noise), biasing n_max low.
// With `noise_correlation` = F the reduced χ² uses the effective degrees of freedom
// N − p·F² (clamped to ≥ 1); F = 1 is the textbook χ²_r. The rule holds for basis functions
// smoother than the correlation, and for the HDF's short drizzle correlation; for smoothly
// correlated noise (PSF-matched images: ξ 0.82, 0.50 at 1, 2 pixels in the XDF's F606W) the
// higher orders take up far less (half at n_max 8). Given the measured correlation
// (`correlation`), each order's best fit counts its exact take-up T = tr((BᵀB)⁻¹BᵀRB)
// (lsq.hpp noise_take_up): dof N − T, and an order is significant when it lowers χ² by more
// than ΔT + order_sigmas·λ√(2Δp), λ = ΔT/Δp.
#pragma once

#include "shapesim/fits_io.hpp"
#include "shapesim/lsq.hpp"
#include "shapesim/records.hpp"

#include <optional>
#include <string>
#include <vector>

namespace shapesim {

struct DecomposeOptions {
    int n_max_min = 0;             ///< first order tried
    int n_max_cap = 15;            ///< highest order (the method's default)
    double chi2_target = 1.0;      ///< stop when χ²_r reaches this …
    double chi2_sigmas = 2.0;      ///< … within this many σ of its noise, √(2/dof)
    double beta_tolerance = 1e-3;  ///< golden-section tolerance on ln β
    double theta_min = 1.0;        ///< smallest resolved scale β/√(n+1), pixels
    double centre_tolerance = 0.01;///< recentring stops below this shift, pixels
    int centre_iterations = 5;     ///< and after this many recentrings
    double order_sigmas = 3.0;     ///< an order must beat the noise's take-up by this many σ
    double bad_fit_chi2r = 1.5;    ///< a kept fit above this χ²_r is flagged "bad_fit"
    /// A model dipping below zero by more than this fraction of its peak, or holding more than
    /// this fraction of its light below zero, on its image's pixels (render.hpp pixel_holes; an
    /// intrinsic model through its PSF, as the data see it), is flagged "holes": light is never
    /// negative, and such a model rings (noise fitted, a truncated series).
    double max_hole = 0.1;
    /// A model with more than this fraction of its light (as the data see it) where no datum
    /// constrains it — outside the stamp, on a neighbour's masked pixels, at zero weight — is
    /// flagged "unsupported": its scale ran away to take up a neighbour's wings or to
    /// extrapolate past the edge (XDF: a 15-pixel source fitted with β 9.7 pixels and 48 times
    /// its aperture flux). Well-fitted models put ≤ 2% there (HDF: none above 0.1).
    double max_unsupported = 0.2;
    double noise_correlation = 1.0;///< F for the effective degrees of freedom (see above)
    /// The noise's measured pixel-to-pixel correlation (shapesim-detect's noise model). When
    /// given, every order's fit counts its exact noise take-up (lsq.hpp noise_take_up) in its
    /// degrees of freedom, χ²_r and order test, instead of p·F² (see "Correlated noise").
    std::optional<NoiseCorrelation> correlation;
    /// Where the order search ends at n_max 0 (a round Gaussian), try an elliptical Gaussian
    /// (see "The elliptical lowest order" above), its shear less the noise's share.
    bool elliptical = true;
    LsqSolver solver = LsqSolver::automatic;
    /// With a PSF (unit flux, the stamp's pixels) every fit is of the intrinsic model through
    /// it (lsq.hpp fit_convolved_shapelets): β, n_max, centre and the constraints are the
    /// intrinsic model's, χ² that of its convolution. Without one, the observed-frame model
    /// (the paper's choice).
    std::optional<CartesianModel> psf;

    /// Throws Error (field named) when a value is out of range.
    void validate() const;
};

/// One order's best fit, for the record and for diagnostics.
struct OrderTrial {
    int n_max = 0;
    double beta_pix = 0.0;
    double chi2r = 0.0;
};

/// One band's part of a joint fit (decompose_bands()).
struct BandFit {
    ShapeletFit fit;
    double chi2r = 0.0;            ///< this band's effective χ²_r
    double flux_error = 0.0;       ///< 1σ, with β's and truncation's shares
    double truncation_error = 0.0;
    bool templated = false;        ///< the stack's shape times an amplitude (see below)
};

/// The result of decompose().
struct Decomposition {
    ShapeletFit fit;       ///< the fit kept (model centre, β, n_max inside)
    double chi2r = 0.0;    ///< χ²_r with the effective degrees of freedom
    std::string stop;      ///< why the search stopped: chi2_target, flattened, n_max_cap,
                           ///< stamp_small
    bool converged = false;///< χ²_r ≤ chi2_target (+ its noise allowance)
    bool elliptical = false;  ///< the model is the elliptical lowest order (g1, g2 below)
    double g1 = 0.0, g2 = 0.0;
    bool bad_fit = false;  ///< χ²_r > bad_fit_chi2r: not a faithful model
    double hole = 0.0;     ///< its holes' depth, of the peak (render.hpp pixel_holes) …
    double negative_light = 0.0;  ///< … and the light below zero, of the total
    bool holes = false;    ///< either above max_hole
    double unsupported_light = 0.0;  ///< its light off the data (NaN: none positive)
    bool unsupported = false;          ///< above max_unsupported
    double flux_error = 0.0;  ///< 1σ, with β's and truncation's shares (see decompose())
    double truncation_error = 0.0;  ///< truncation's share alone
    long fits = 0;         ///< linear fits performed
    std::vector<OrderTrial> trials;  ///< the best (β, χ²_r) of each order tried
    /// decompose_bands(): every band's fit (bands[0] is `fit`; empty from decompose()); the
    /// fields above are the joint fit's (χ²_r, stop, flags, holes) and the reference band's
    /// (flux errors).
    std::vector<BandFit> bands;
};

/// One band's stamp for decompose_bands(): every band's the same pixels (the detection's box).
struct BandStamp {
    const ImageArray* image = nullptr;
    const ImageArray* weight = nullptr;
    const MaskArray* mask = nullptr;
    std::optional<CartesianModel> psf;   ///< the band's PSF (else DecomposeOptions::psf)
    double noise_correlation = 1.0;      ///< the band's F
    /// Its weight in the stack whose centroid recentring follows: 1/σ of its pixel noise, so
    /// the stack is S/N-weighted like a χ² detection image.
    double signal_weight = 1.0;
    std::optional<NoiseCorrelation> correlation;  ///< the band's ξ (else DecomposeOptions')
};

/// The order an elliptical lowest-order model is expanded to.
constexpr int elliptical_order = 4;
/// The round Gaussian of scale beta_pix sheared by (g1, g2), |g| < 1, with a_{0,0} = 1 before
/// the shear, expanded to n_max elliptical_order about (0, 0).
ShapeletModel elliptical_gaussian(double beta_pix, double g1, double g2);

/// Orders above the chosen n_max fitted to estimate the truncation error of the flux.
constexpr int truncation_orders = 4;
/// One fit at (x, y, β, n_max): through `options.psf` when given, else the plain fit.
ShapeletFit fit_model(const ImageArray& image, const ImageArray& weight, const MaskArray* mask,
                      double x, double y, double beta_pix, int n_max,
                      const DecomposeOptions& options);
/// Effective degrees of freedom of `fit`: pixels − p·F² (≥ 1).
double effective_dof(const ShapeletFit& fit, double noise_correlation);
/// χ²_r of `fit` with those degrees of freedom.
double effective_chi2r(const ShapeletFit& fit, double noise_correlation);
/// The χ² the noise takes up when n_max rises from `from` to `to`, plus `order_sigmas` of its
/// scatter: F²·(Δp + order_sigmas·√(2Δp)).
double noise_uptake(int from, int to, const DecomposeOptions& options);
/// Whether χ²_r (of `fit`) is within the target and its noise allowance.
bool within_target(const ShapeletFit& fit, double chi2r, const DecomposeOptions& options);

/// Decompose `image` (weights, optional mask as in fit_shapelets) starting from centre
/// (x, y) in stamp FITS coordinates and scale `beta_start` pixels (e.g. the detection's a).
/// Throws Error when the stamp has too few usable pixels for the lowest order.
/// The flux error adds to the fixed-β covariance error the part β's own uncertainty brings
/// (flux and β are strongly correlated: flux = 2√π β Σ a_{n,0}): from the profile χ²(ln β)
/// at ±5%, σ²_lnβ = 2F²/∂²χ², and σ_F² = σ²_fixed + (∂F/∂ln β)² σ²_lnβ (F the correlated-noise
/// factor, which flattens χ²'s curvature as it inflates smooth-function variances), and the
/// part truncation brings: a χ²-chosen n_max leaves out orders the noise hides, which still
/// carry flux (a_{n,0}, n even, all weigh equally in F). It is estimated from the fit
/// `truncation_orders` higher at the same centre and β: σ_t² = ΔF² − (σ'² − σ²), ≥ 0.
/// On random galaxy-like models at S/N 20 this takes the flux pulls' rms from 2.8 to 1.4.
Decomposition decompose(const ImageArray& image, const ImageArray& weight, const MaskArray* mask,
                        double x, double y, double beta_start, const DecomposeOptions& options);

/// The joint decomposition of several bands (issue 17): one centre, β and n_max for all,
/// each band its own coefficients. The search is decompose()'s with χ² summed over the bands,
/// the effective degrees of freedom Σ_b (N_b − p F_b²), an order's noise take-up
/// Σ F_b²·Δp + order_sigmas·√(2Δp Σ F_b⁴), the centre the centroid of the bands' models
/// summed with weights `signal_weight`; an elliptical lowest order is one sheared shape with
/// an amplitude per band. Flux errors per band as decompose() gives them, β's share from the
/// joint profile χ². bands[0] is the reference band: its fit is `fit`, its errors the
/// record's. One band is exactly decompose().
///
/// A faint band's own coefficients at the order the bright bands chose are mostly its noise,
/// which a simulation drawn from them would add to its own (the XDF's F140W colours came out
/// twice as broad). So with several bands, each band is also fitted as the S/N-weighted
/// stack's shape times one amplitude, and takes that model (BandFit::templated: its colour,
/// no gradient of its own) unless its own coefficients take up more χ² than the noise would
/// with p − 1 more parameters, F_b²·(Δp + order_sigmas·√(2Δp)) — the order test's rule. Its
/// flux error stays its own fit's.
Decomposition decompose_bands(const std::vector<BandStamp>& bands, double x, double y,
                              double beta_start, const DecomposeOptions& options);

/// 1σ error of the model flux 2√π β Σ a_{n,0} from the fit's covariance.
double flux_error(const ShapeletFit& fit);

/// The `shapesim.shapelet/1` record of a decomposed source (DESIGN §2).
///  - centre in the parent image's FITS pixels (stamp origin added), β in arcsec at
///    `pixel_scale`, coefficients, chi2r (effective), flux, mag (`zero_point`), and
///    `coeff_errors` ([[σ_re, σ_im], …] in the coefficients' order), `flux_err` (and its
///    truncation share `flux_err_truncation`), `stop`,
///    `beta_pix`, `trials` ([[n_max, β_pix, χ²_r], …]), `fits`.
///  - flags: "converged" or "not_converged"; "n_max_cap"; "bad_fit" (χ²_r above
///    bad_fit_chi2r: the model misses real structure); "holes" (the model dips below zero
///    by more than max_hole of its peak or of its light; `hole_depth`, `negative_light`);
///    "unsupported" (more than max_unsupported of its light off the data, `unsupported_light`);
///    "neighbour" (the source was
///    deblended, or more than 5% of the pixels within the model's reach β√(n_max+1) belong
///    to a neighbour); "edge" (the segment or the paper's 3a + 5 square cut by the image edge);
///    "noise" (model flux below 3σ of the noise, truncation's share left out: a probable noise
///    detection). ("bright_star", near_bright_star(), is the caller's: it needs the star list.)
///  - the source's fields are carried through; those the schema reuses (x, y, flux, flux_err,
///    mag, flags, …) as `source_x`, `source_flux`, `source_flags`, ….
/// Without a zero point (absent or null in the source record) `mag` is left out. A model fitted
/// through `psf` (DecomposeOptions::psf) is intrinsic: "frame": "intrinsic", with the PSF's
/// `psf_beta` (arcsec) and `psf_n_max`.
/// A joint fit (decomposition.bands, named by `bands` in the same order) writes `bands`
/// (BandCoefficients: coefficients, flux, flux_err, mag with the band's zero point, chi2r,
/// coeff_errors, flux_err_truncation); the record's own fields are the reference band's
/// (`band` names it), `zero_point` must be its zero point, and "noise" is flagged only when
/// no band's flux reaches 3σ.
struct BandLabel {
    std::string band;
    std::optional<double> zero_point;
};
ShapeletRecord shapelet_record(const SourceRecord& source, const Decomposition& decomposition,
                               const Stamp& stamp, double pixel_scale,
                               std::optional<double> zero_point,
                               const CartesianModel* psf = nullptr,
                               const std::vector<BandLabel>& bands = {});

/// Whether a star brighter than the galaxy lies close enough for its wings to touch the
/// galaxy's model: the star's circle of twice its radius — its Kron radius (kron_radius·a, or
/// 1.5·FWHM when the record has neither) or, for a galaxy ten times fainter than the star, its
/// isophote's, √(iso_area/π), when that is larger (the XDF's I = 19 star: 3.9 against 41
/// pixels, its halo deblended into "galaxies" 5000 times fainter) — overlaps the model's reach,
/// β√(n_max+1) about its centre. All in the parent image's FITS pixels; `galaxy_flux` and the
/// stars' fluxes in the same units.
bool near_bright_star(double x, double y, double reach, double galaxy_flux,
                      const std::vector<SourceRecord>& stars);

}  // namespace shapesim
