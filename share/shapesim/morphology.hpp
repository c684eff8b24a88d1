// The morphology PDF of the method (paper §3–4.1, DESIGN §4): aligned shapelet models as
// points of a parameter space (c_{n,m} = a_{n,m}/a_{0,0} as |c| and arg c for m > 0, the real
// c_{n,0}, β in arcsec and magnitude), smoothed by Epanechnikov kernels of widths λ and
// resampled by Silverman's bootstrap: a parent by weight, perturbed by λ on every axis it has,
// then rotated and reflected at random. Options draw shapes conditional on magnitude, move
// parents to their nearest non-negative shapes, mix several parents, and carry several bands
// with denoised colours.
// Derivation: docs/algorithms.md#the-morphology-pdf
#pragma once

#include "shapesim/model.hpp"
#include "shapesim/records.hpp"
#include "shapesim/rng.hpp"

#include <Eigen/Dense>

#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace shapesim {

/// How a model was aligned: aligned = reflect?(rotate(model, rotation)).
struct Alignment {
    double rotation = 0.0;  ///< radians, as transform.hpp rotate()
    bool reflected = false; ///< reflected about the x axis after the rotation
};

/// The aligned model (docs/algorithms.md#alignment) and how it was reached.
ShapeletModel align(const ShapeletModel& model, Alignment* how = nullptr);
/// The inverse of align(): the original model from the aligned one.
ShapeletModel unalign(const ShapeletModel& aligned, const Alignment& how);

/// One real galaxy: its aligned shape normalised by a_{0,0}.
struct MorphologyPoint {
    std::string id;
    int n_max = 0;
    double beta = 0.0;  ///< arcsec
    double mag = 0.0;
    double weight = 1.0;            ///< parent-selection weight (relative)
    /// From a shape-only field (isolated-galaxy cutouts, a catalogue's selection): weight 0, it
    /// adds nothing to the counts, but conditional draws (--neighbours) take its shape.
    bool shape_only = false;
    double psf_beta = 0.0;          ///< an intrinsic model's PSF scale (arcsec; 0: none)
    std::vector<Complex> shape;     ///< c_{n,m} = a_{n,m}/a_{0,0}, aligned; c_{0,0} = 1
    Alignment alignment;            ///< how the real model was aligned
    /// |c| and arg c of `shape` (derived: Morphology::prepare() fills them for the draws).
    std::vector<double> modulus, phase;
    double hole = 0.0;  ///< hole_depth() of the shape (derived, prepare())
    /// Multi-band: each band's aligned coefficients over the reference band's a_{0,0}, in
    /// Morphology::bands order (empty for a one-band model).
    std::vector<std::vector<Complex>> band_shapes;
    /// Magnitude gap to the nearest other counted point (weight > 0; derived, prepare(); ∞ when
    /// alone): conditional draws smooth its magnitude over max(λ_mag, gap), so sparse bright
    /// parents spread over the gaps between them instead of spiking at their own magnitudes.
    double mag_gap = 0.0;
    /// The shape's mean |z|² about its centre over its flux, in units of β² (derived,
    /// prepare(); NaN when not positive): a mixture's size is set from it (draw_galaxy, mix).
    double size2 = 0.0;
    /// adaptive_epsilon() of the shape, for n_max ≥ 2 (derived, prepare(); NaN otherwise): the
    /// ellipticity a round parent borrows.
    Complex adaptive_epsilon;
    /// How far the shape was moved to be non-negative, ‖c' − c‖/‖c‖ (0: as fitted).
    double positivity_change = 0.0;
};

/// ε (reduced-shear form) of the adaptive moments (shear_estimate.hpp) of a unit-β shape drawn
/// at β = 3 pixels: the ellipticity a moments-based measurement sees, where the unweighted
/// moments weigh a model's faint outskirts. With psf_scale > 0, as the reference estimator sees
/// it through a round Gaussian PSF of β = psf_scale (in the shape's β): the shape convolved, its
/// adaptive moments less the PSF's (the linear correction). NaN when its flux is not positive,
/// the moments do not converge or the corrected ones are not positive definite.
Complex adaptive_epsilon(const std::vector<Complex>& shape, int n_max, double psf_scale = 0.0);
/// Smoothing length of every axis.
struct SmoothingLengths {
    double phase_deg = 15.0;
    double beta = 0.0;   ///< arcsec
    double mag = 0.0;
    /// Per packed polar index (n, m): of |c| for m > 0, of c for m = 0; index 0 unused (0).
    std::vector<double> coefficient;
    /// Multi-band: the colour kernel's width h, in units of the population's own spread.
    double colour = 0.0;
    bool is_delta() const;
};

/// Options of build_morphology().
struct SmoothOptions {
    double k = 4.0;                      ///< λ = k × mean nearest-neighbour separation
    double phase_deg = 15.0;             ///< λ_phase
    std::optional<double> beta, mag, modulus;  ///< overrides (modulus: every coefficient axis)
    bool delta = false;                  ///< every λ = 0
    /// Multi-band: keep each parent's colours as measured, noise and all (by default they are
    /// denoised: see build_morphology).
    bool keep_colour_noise = false;
    /// Keep every shape as fitted, light below zero and all (by default, outside δ mode, each
    /// is moved to its nearest non-negative shape: positivity.hpp,
    /// docs/algorithms.md#positive-models).
    bool keep_negative = false;
    /// Multi-band: the colour kernel's width h (docs/algorithms.md#several-bands).
    double colour = 0.25;
    void validate() const;
};

/// A real field the models came from: its area and the magnitude of every galaxy detected in
/// it (all of them, kept as models or not), so that a simulation can draw the real number
/// density at any magnitude limit.
struct SourceField {
    std::string image;           ///< the records' "image" (empty: the one field of them all)
    double area_arcmin2 = 0.0;
    std::vector<double> mags;    ///< sorted
    /// Its counts are complete to this magnitude (∞: to every one, the single-field case).
    double completeness = std::numeric_limits<double>::infinity();
    /// Its stars' magnitudes, sorted, when smooth was given them (--stars): shapesim-sample
    /// draws the field's star counts by default (sample.hpp field_star_counts). Empty: counted,
    /// none found; none: not counted.
    std::optional<std::vector<double>> star_mags = std::nullopt;
    /// Galaxies per arcmin² with mag ≤ `mag_limit`.
    double density(double mag_limit) const;
};

/// Several fields of different depths, counted together (issue 14 §2–3). Each magnitude bin
/// (0.25 mag wide) takes its galaxies from the fields whose counts are complete through it, over
/// their total area; where none is, from the deepest ones. One field: its own density().
double field_density(const std::vector<SourceField>& fields, double mag_limit);
/// The fields counted at magnitude `mag` by field_density() (indices).
std::vector<std::size_t> fields_counted(const std::vector<SourceField>& fields, double mag);
/// Where a field's counts stop being complete: the upper edge of the 0.5-mag bin holding most
/// of its galaxies (the turnover); ∞ for fewer than 10 galaxies.
double count_turnover(const std::vector<double>& sorted_mags);

/// A magnitude from power-law counts, d log₁₀ N / dm = `slope` on [lo, hi], by the inverse CDF
/// of one uniform deviate u ∈ [0, 1) (stars and fitted galaxy counts alike).
double power_law_magnitude(double u, double slope, double lo, double hi);

/// Galaxy number counts as a power law, dN/dm = 10^{log_density + slope (m − pivot)} per arcmin²
/// per magnitude, on [bright, faint] (issue 14 §3). A few-arcmin² field holds one or two galaxies
/// at its bright end: drawn as they are (a parent's magnitude, perturbed), a 6 arcmin²
/// simulation gets their Poisson luck times fifty; fitted, the bright end follows the slope the
/// whole field measures.
///
/// Or a tabulated law (`knot_mag`, `knot_log` non-empty: count_law(), read_count_law()):
/// log₁₀ dN/dm per arcmin² per magnitude at the knots, exponential (a power law) between them
/// and along the end segments' slopes beyond; the same galaxies per magnitude whatever the
/// limit, since nothing is fitted.
struct CountModel {
    double pivot = 25.0;
    double log_density = 0.0;  ///< log₁₀ dN/dm at the pivot (per arcmin² per magnitude)
    double slope = 0.0;        ///< d log₁₀ N / dm
    double bright = 0.0, faint = 0.0;  ///< the magnitudes drawn
    std::size_t galaxies = 0;  ///< how many real galaxies the fit saw
    std::vector<double> knot_mag, knot_log;  ///< a tabulated law (ascending magnitudes)
    std::string source;        ///< where a tabulated law comes from (citation or file)
    bool tabulated() const { return !knot_mag.empty(); }
    /// log₁₀ dN/dm per arcmin² per magnitude at `mag` (either form).
    double log_dndm(double mag) const;
    /// Galaxies per arcmin² between lo and hi (within [bright, faint]).
    double density(double lo, double hi) const;
    double density() const { return density(bright, faint); }
    /// A magnitude in [bright, faint] from one uniform deviate u ∈ [0, 1).
    double magnitude(double u) const;
};

/// The I-band (HST F814W, AB) galaxy counts drawn by default, on [16, 31]: the COSMOS2020 i-band
/// counts (Weaver et al. 2022, ApJS 258, 11, Table 2: log₁₀ dN/dm per deg² per magnitude in
/// 0.5-mag bins, 19.25–25.75, where the catalogue is complete), fainter along d log₁₀ N / dm =
/// 0.26 (the HDF-N I₈₁₄ counts to I = 31, Marín-Franch & Aparicio 2003), brighter along the
/// table's own bright slope (0.44). docs/sample.md#galaxy-counts compares it with the LSST
/// Science Book's i-band law and the shipped fields.
CountModel count_law();
/// A count law from a text file of lines "mag log10_dN_dm" (galaxies per deg² per magnitude,
/// AB; '#' comments), ascending magnitudes, at least two; drawn on [first − 3, last + 3] along
/// the end slopes. Error naming the file and line.
CountModel read_count_law(const std::string& path);

/// The power law of most likelihood (Poisson, unbinned) for the galaxies of every field between
/// `bright` and the fainter of `faint` and the field's completeness, each field over its own
/// range and area. The slope solves the score equation (the mean magnitude it predicts equals the
/// galaxies' own; |slope| ≤ 3), the density then gives back the number of galaxies seen. Throws
/// Error with fewer than 2 galaxies in range, or when they all share one magnitude.
CountModel fit_counts(const std::vector<SourceField>& fields, double bright, double faint);

/// The morphology model that `shapesim-smooth` writes and `shapesim-sample` reads.
struct Morphology {
    static constexpr const char* schema = "shapesim.morphology/1";
    int n_max = 0;                       ///< largest n_max of the points
    std::vector<MorphologyPoint> points;
    SmoothingLengths lambda;
    std::optional<double> zero_point;    ///< of the magnitudes (when every input agreed)
    /// "observed": models hold their image's PSF (the paper's); "intrinsic": fitted through
    /// it (shapesim-decompose --psf), drawn through the target PSF. One frame per model.
    std::string frame = "observed";
    /// The real fields, when smooth was told their areas; a simulation draws their density
    /// (field_density) and, with several, the points' weights make the drawn magnitudes follow it.
    std::vector<SourceField> source_fields;
    /// The shape-only fields' images (their points are `shape_only`).
    std::vector<std::string> shape_fields;
    /// Multi-band: the bands (the first the reference, whose magnitudes `mag` are) and their
    /// zero points (of the real images, when every record gave one).
    std::vector<std::string> bands;
    std::vector<std::optional<double>> band_zero_points;
    /// Multi-band: the band the points' shapes and magnitudes are (index into `bands`), and
    /// the mean and covariance of the points' flux ratios s_b (the reference's entry 1, its
    /// row and column 0). Without a reference the colours are not perturbed.
    std::optional<std::size_t> reference_band;
    std::vector<double> colour_mean;
    Eigen::MatrixXd colour_covariance;
    Eigen::MatrixXd colour_root;         ///< V^{1/2} (prepare() fills it)
    Json provenance = Json::object();    ///< input hash, options, program version

    Json to_json() const;
    /// Throws Error naming the field on a wrong schema or value.
    static Morphology from_json(const Json& document);
    /// The model in file `path` ("-": stdin); Error naming the file on unreadable or invalid
    /// input.
    static Morphology read(const std::string& path);
    /// Fill every point's derived modulus and phase, and colour_root (build_morphology and
    /// from_json do; call it again after changing a shape or the colour covariance).
    void prepare();
};

/// Σ_{n even} Re c_{n,0} of a packed shape: its flux over 2√π β a_{0,0}.
double even_sum(const std::vector<Complex>& shape);

/// Multi-band: band b's flux over the reference band's (the point's shape),
/// s_b = Σ_{n even} c_{b,n,0} / Σ_{n even} c_{n,0} (NaN when the reference's sum is 0).
double flux_ratio(const MorphologyPoint& p, std::size_t band);

/// Mean over the values of the distance to the nearest other value (0 for fewer than two).
double mean_nearest_neighbour_separation(std::vector<double> values);

/// How many of the model's points are shape-only (MorphologyPoint::shape_only: only
/// magnitude-conditional draws take their shapes).
long count_shape_only(const Morphology& morphology);

/// Align every record's model and compute the smoothing lengths. Throws Error when a record
/// has a_{0,0} ≤ 0 or no magnitude (the caller filters such records first).
Morphology build_morphology(const std::vector<ShapeletRecord>& records,
                            const SmoothOptions& options);

// Choosing the records (shapesim-smooth): which become points, their parent-selection weights
// and fields, and the model's provenance.
/// Which shapelet records become the model's points (shapesim-smooth's selection).
struct RecordSelection {
    std::vector<std::string> required;  ///< flags every kept record holds (an entry "A|B": either)
    std::vector<std::string> rejected;  ///< flags no kept record holds
    std::optional<double> mag_limit;    ///< kept records are at most this faint
    /// The fields' images, counted ones first, that records name in "image" (empty: one field,
    /// "image" not read).
    std::vector<std::string> images;
    std::string weight_field;  ///< numeric record field of the parent-selection weight (empty: 1)
    /// Weight each kept galaxy of a field by the field's galaxies left out near its magnitude
    /// as well (weight_by_kept_fraction()).
    bool weight_left_out = false;
};
/// Why a record is left out, the first reason in this order: "not <required>", "<rejected
/// flag>", "no magnitude", "fainter than --mag-limit", "a_00 <= 0"; empty when it is kept.
std::string drop_reason(const ShapeletRecord& record, const RecordSelection& selection);

/// The records a selection keeps, and an account of the rest.
struct SelectedRecords {
    std::vector<ShapeletRecord> kept;
    std::vector<double> weights;          ///< each kept record's parent-selection weight
    std::vector<std::size_t> field;       ///< each kept record's index in the selection's images
    std::map<std::string, long> dropped;  ///< records left out, by drop_reason()
    long read = 0;                        ///< records read
    /// The input's identity for the provenance: FNV-1a over the records' compact dumps.
    std::uint64_t hash = fnv1a_64("");
};
/// Read every shapelet record of `reader` and keep the selected ones. Every galaxy with a
/// magnitude, kept or not, joins its counted field's `mags` (unsorted; fields[i] is the
/// selection's images[i], or fields[0] without images). Throws Error placed in the input on a
/// bad record, an image not among the selection's, or a bad weight.
SelectedRecords select_records(JsonlReader& reader, const RecordSelection& selection,
                               std::vector<SourceField>& fields);

/// Several fields counted together (field_density()): each kept galaxy of a counted field
/// (field[i] < fields.size()) stands for weights[i] / (the area counted at its magnitude)
/// galaxies per arcmin², none where its own field is not counted (fainter than its
/// completeness). Shape-only galaxies' weights, and one field's, are left as they are.
void weight_by_counted_area(const std::vector<SourceField>& fields,
                            const std::vector<ShapeletRecord>& kept,
                            const std::vector<std::size_t>& field, std::vector<double>& weights);

/// Each kept galaxy of a counted field also stands for the field's galaxies left out near its
/// magnitude (noise detections, edges, bad fits): its weight × (the field's galaxies) / (its
/// kept galaxies) in its 0.5-mag bin, so parents drawn by weight have the magnitudes of every
/// galaxy the field holds, not only of those that fitted (issue 36 §2: the faint galaxies left
/// out are the small ones). Shape-only galaxies are left as they are.
void weight_by_kept_fraction(const std::vector<SourceField>& fields,
                             const std::vector<ShapeletRecord>& kept,
                             const std::vector<std::size_t>& field, std::vector<double>& weights);

/// Ids are per image: the short name of each image that prefixes its points' ids
/// ("hdfn_f814w_v2", "AEGIS_F814w_images_01[1]": no folder, no ".fits"); where two clash, the
/// first takes its whole name, which tells them apart: a simulation's `parent` names one real
/// galaxy.
std::vector<std::string> image_labels(const std::vector<std::string>& images);

/// The model's points built from `selected.kept` (in order) take their fields' marks: with
/// several images, each id its image's label (image_labels()); with images, a point of a
/// shape-only field (index ≥ `counted_fields`) is shape_only and weighs 0, every other its
/// selected weight. Returns the number of shape-only points.
long mark_point_fields(Morphology& morphology, const SelectedRecords& selected,
                       const RecordSelection& selection, std::size_t counted_fields);

/// shapesim-smooth's provenance of a model built from `selected` (Morphology::provenance): the
/// program and version, the input's name, record count and FNV-1a hash, the records dropped by
/// reason, and the smoothing and selection options.
Json smooth_provenance(const std::string& input, const SelectedRecords& selected,
                       const RecordSelection& selection, const SmoothOptions& options);

/// One drawn galaxy, centred at (0, 0), before placement on the sky.
struct DrawnGalaxy {
    ShapeletModel model;    ///< rotated and reflected, β in pixels of the target scale
    std::size_t parent = 0; ///< index into Morphology::points: the shape's parent
    std::size_t mag_parent = 0;  ///< the parent whose magnitude was perturbed (= parent
                                 ///< unless drawn conditionally on magnitude)
    double mag = 0.0, flux = 0.0, beta = 0.0;  ///< beta in arcsec
    double rotation = 0.0;  ///< radians, applied after the parent's alignment
    bool reflected = false; ///< reflected about x before the rotation
    double perturbation = 0.0;  ///< ‖c' − c‖/‖c‖ over the shape vector
    int redraws = 0;        ///< perturbations refused (non-positive flux, β ≤ 0, too faint,
                            ///< too large)
    /// Multi-band: each band's model (Morphology::bands order; the reference's is `model`), in
    /// the reference band's units: band b's flux over `flux` is the drawn colour's ratio.
    std::vector<ShapeletModel> band_models;
    /// A mixture (DrawOptions::mix): every parent (indices into Morphology::points) and its
    /// weight, `parent` (the shape parent) first and the heaviest; empty for a perturbed draw.
    std::vector<std::size_t> parents;
    std::vector<double> weights;
};

/// Cumulative parent weights for draw_galaxy(), over the points with mag ≤ `mag_limit`.
/// Throws Error when no point qualifies.
std::vector<double> parent_table(const Morphology& morphology, double mag_limit);

/// How draw_galaxy() chooses shapes (docs/algorithms.md#conditional-on-magnitude).
struct DrawOptions {
    int neighbours = 0;       ///< K; 0: the paper's draw (shape and magnitude of one parent)
    double size_slope = 0.3;  ///< s in r ∝ L^s when a shape moves to another magnitude
    double max_mag_shift = 2.0;  ///< only parents this close to the drawn magnitude (and the
                                 ///< nearest): a shape is not stretched across the field's range
    /// Perturbations with ‖c' − c‖/‖c‖ above this are redrawn: a shape changed by as much as
    /// it has is no longer its parent's (nor, often, a galaxy's).
    double max_perturbation = 0.5;
    /// Draws whose holes are deeper than their parent's by more than this fraction of the
    /// peak (hole_depth) are redrawn: a perturbation must not ring below zero where the real
    /// galaxy does not. A draw with a higher peak than its parent's (brighter, or smaller) is
    /// allowed the parent's holes only at their depth in flux (parent hole × parent peak /
    /// draw peak, the peak ∝ flux/β²).
    double hole_allowance = 0.01;
    std::vector<std::size_t> by_magnitude;  ///< the parents in magnitude order (magnitude_order)
    /// Conditional draws take their magnitude from these counts (fit_counts), not from a
    /// parent's: then the shape parent is the only parent.
    std::optional<CountModel> counts;
    /// M ≥ 2: a conditional draw is a mixture of M parents, not a perturbation (see "Mixtures"
    /// above; neighbours ≥ M); 0 or 1, or neighbours 0: the perturbed draw.
    int mix = 0;
    void validate() const;
};

/// The counts a conditional draw takes its magnitudes from: a power law fitted to the model's
/// fields (fit_counts) from half a `max_mag_shift` above the brightest parent (as far as a
/// parent's shape is moved up at the bright end) to `mag_limit`. None when the draw is not
/// conditional (neighbours 0, δ mode) or the model recorded no field.
std::optional<CountModel> conditional_counts(const Morphology& morphology, const DrawOptions& draw,
                                             double mag_limit);

/// A count law (`law`, tabulated or not) as a conditional draw's counts: from the law's bright end
/// to `mag_limit`. None when the draw is not conditional (neighbours 0, δ mode). Error when the
/// limit is not fainter than the law's bright end.
std::optional<CountModel> law_counts(const Morphology& morphology, const DrawOptions& draw,
                                     const CountModel& law, double mag_limit);

/// The half-width of a conditional draw's magnitude kernel about its magnitude parent `p`:
/// λ_mag, widened to the gap to the nearest counted parent (mag_gap) but never past half of
/// max_mag_shift, so the counts stay smooth where parents are sparse.
double conditional_mag_spread(const MorphologyPoint& p, double lambda_mag, const DrawOptions& draw);

/// The points a conditional draw can take a shape from (weight > 0 or shape-only, mag ≤
/// `mag_limit`), brightest first (ties by index).
std::vector<std::size_t> magnitude_order(const Morphology& morphology, double mag_limit);

/// Draw one galaxy from `stream` (parent, perturbation, rotation, reflection — in that order;
/// conditional: parent, magnitude, shape parent, the rest). Perturbations giving a
/// non-positive flux sum, β ≤ 0, mag > `mag_limit`, a perturbation above `max_perturbation`
/// or holes deeper than the parent's by `hole_allowance` are redrawn, the shape's perturbation
/// halved every 100 redraws (at most 1000 times, then the parent unperturbed).
DrawnGalaxy draw_galaxy(const Morphology& morphology, const std::vector<double>& parents,
                        RandomStream& stream, double pixel_scale, double zero_point,
                        double mag_limit, const DrawOptions& draw = DrawOptions{});

/// A galaxy fainter than the catalogue the model was trained on (the sky's unresolved light,
/// issue 36 §4): its magnitude from `draw.counts` (the fitted counts, extrapolated from
/// `counts->bright` to `counts->faint`), its shape parent among the `draw.neighbours` parents
/// nearest that magnitude (the faintest), mixed with draw.mix − 1 partners as a mixture draw is
/// (in δ mode, or mix ≤ 1, the parent alone), its size scaled to that magnitude as L^size_slope.
/// Throws Error without counts.
DrawnGalaxy draw_faint_galaxy(const Morphology& morphology, RandomStream& stream,
                              double pixel_scale, double zero_point, const DrawOptions& draw);

/// Radius (pixels) beyond which a model of scale β_pix and order n_max contributes less than
/// ~1e-6 of its peak: β(√(2 n_max + 1) + 5) — the Gaussian envelope past the basis's last
/// turning point. Sample uses it to decide which tiles an object reaches.
double model_reach(double beta_pix, int n_max);

}  // namespace shapesim
