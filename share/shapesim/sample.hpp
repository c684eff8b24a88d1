// Populating a sky field with objects drawn from the morphology PDF (paper §4.1–4.2,
// DESIGN §4, §6): galaxies by Silverman's bootstrap (morphology.hpp draw_galaxy), stars from
// a magnitude distribution, uniform positions. Every draw comes from the counter-based stream
// of (seed, object key, purpose), keyed by sky cells of `cell` × `cell` pixels, so any
// object's record is the same whatever the tiling; a tile holds every object whose reach
// (model_reach plus `margin` pixels) meets it.
// Derivation: docs/algorithms.md#sampling-a-field
#pragma once

#include "shapesim/geometry.hpp"
#include "shapesim/morphology.hpp"
#include "shapesim/records.hpp"

#include <cstdint>
#include <functional>
#include <map>
#include <ostream>
#include <optional>
#include <string>
#include <vector>

namespace shapesim {

/// The stars' magnitude distribution: power-law counts, d log₁₀ N / dm = `slope` between
/// `mag_min` and `mag_max`, or a histogram (`bins`: [lo, hi) edges and relative counts, flat
/// within a bin) when given.
struct StarCounts {
    double density = 0.0;  ///< stars per arcmin² between the magnitude limits
    double slope = 0.1;
    double mag_min = 18.0, mag_max = 29.0;
    struct Bin {
        double lo = 0.0, hi = 0.0, count = 0.0;
    };
    std::vector<Bin> bins;
    /// A magnitude from one uniform deviate u ∈ [0, 1) (inverse CDF).
    double magnitude(double u) const;
    void validate() const;
};

/// The star counts of the model's real fields (SourceField::star_mags, smooth --stars): their
/// stars brighter than `mag_limit` per arcmin² of the fields that counted them, in 0.5-mag
/// bins from the brightest (flat within a bin, as a --star-histogram); density 0 when those
/// fields hold none. None when no field counted its stars.
std::optional<StarCounts> field_star_counts(const std::vector<SourceField>& fields,
                                            double mag_limit);

/// Read a star-count histogram: lines "mag_lo mag_hi count" ('#' comments, blank lines
/// allowed); throws Error naming file and line.
std::vector<StarCounts::Bin> read_star_histogram(const std::string& path);

struct SampleOptions {
    std::uint64_t seed = 0;
    double density = 700.0;            ///< galaxies per arcmin² (brighter than mag_limit)
    std::optional<std::uint64_t> count;///< exact number of galaxies instead
    /// Shape-noise cancellation (GREAT08, STEP2): galaxies in rings of `ring` copies of one
    /// draw, copy m turned by m·180°/ring (2: rotated pairs, 90° apart), each at its own
    /// position; the ellipticities of a ring sum to zero. Each cell draws whole rings (a
    /// Poisson number of density/ring; `count` must be a multiple). 1: every galaxy its own.
    int ring = 1;
    double mag_limit = 29.0;           ///< nothing fainter
    double zero_point = 0.0;           ///< of the output fluxes
    double margin = 0.0;               ///< pixels added to every reach (PSF, …)
    long cell = 4096;                  ///< sky cells of cell × cell pixels key the draws
    /// Shapes conditional on magnitude (morphology.hpp; `by_magnitude` is filled here).
    /// With draw.counts (conditional_counts), conditional draws take their magnitudes from
    /// those fitted counts; without, from a parent's magnitude, perturbed.
    DrawOptions draw;
    /// The sky's unresolved galaxies: galaxies fainter than mag_limit down to this magnitude,
    /// from the fitted counts extrapolated (draw_faint_galaxy), ids "u<k>" (cell c > 0:
    /// "u<c>.<k>"), `"below_limit": true`. None: nothing fainter than mag_limit.
    std::optional<double> faint_limit;
    /// Their counts (apply_model_counts fills them): the slope and density of the fitted
    /// counts, on (mag_limit, faint_limit].
    std::optional<CountModel> faint_counts;
    StarCounts stars;
    std::optional<std::uint64_t> star_count;
    void validate() const;
};

/// Where a conditional draw's magnitudes come from (shapesim-sample --counts).
enum class CountSource {
    law,      ///< a count law (count_law(), or a file's): the same at every magnitude limit
    fit,      ///< a power law fitted to the model's fields up to the limit (fit_counts)
    parents,  ///< a parent's magnitude, perturbed
};

/// The model's say in a draw. With CountSource::law, `options.draw.counts` are `law` up to the
/// limit (law_counts); with CountSource::fit (--counts fit), the
/// counts fitted to its real fields (conditional_counts; when they cannot be, an Error naming
/// `model_path` points to --counts parents). Unless `density_given`, `options.density` becomes
/// the counts' (the law's or the fit's), else the real fields' own (field_density()) when the
/// model recorded any.
/// With `options.faint_limit`, `options.faint_counts` are those counts (or ones fitted for them)
/// extrapolated past the limit. The draw options and the faint limit are checked first (Error).
void apply_model_counts(SampleOptions& options, const Morphology& morphology, CountSource source,
                        bool density_given, const std::string& model_path,
                        const CountModel& law = count_law());

/// Counts of what sample_field() drew and emitted.
struct SampleSummary {
    std::uint64_t galaxies = 0, stars = 0;      ///< drawn over the whole field
    std::uint64_t galaxies_out = 0, stars_out = 0;  ///< emitted (in the tile)
    std::uint64_t redraws = 0;                  ///< perturbations refused and redrawn
    std::uint64_t faint = 0, faint_out = 0;     ///< galaxies below mag_limit: drawn, emitted
    std::uint64_t cells = 0, cells_read = 0;    ///< sky cells, and those whose draws were read
    /// The run's summary as shapesim-sample logs it (its elapsed time follows): drawn over
    /// `field` at `density` per arcmin², written (`in_tile`: in the tile), cells, redraws.
    std::string describe(const FieldGeometry& field, double density, bool in_tile) const;
};

/// Clones at the bright end (issue 14 §3): among the galaxies brighter than each limit, the
/// largest number drawn from one real parent.
class ParentShares {
public:
    explicit ParentShares(std::vector<double> mag_limits = {22.0, 24.0, 26.0});
    void add(const ObjectRecord& record);  ///< galaxies with a mag and a parent count
    struct Share {
        double mag_limit = 0.0;
        std::uint64_t galaxies = 0;  ///< brighter than mag_limit
        std::uint64_t largest = 0;   ///< of them, from the commonest parent
        std::string parent;          ///< that parent (the smallest id on ties)
    };
    std::vector<Share> shares() const;
    /// "I < 22: 3/5 from 117; I < 24: …" (the band named `band`).
    std::string summary(const std::string& band = "I") const;

private:
    std::vector<double> limits_;
    std::vector<std::map<std::string, std::uint64_t>> counts_;
};

/// Draw the field's objects and call `emit` for each one in the tile (all, without one),
/// galaxies first, each kind in order of its number. Records carry x, y (field pixels), ra,
/// dec, mag, flux, β, n_max, coefficients at the field's pixel scale, `parent` (the shape's),
/// and extra `rotation` (degrees), `reflected`, `perturbation`, `reach` (pixels, with the
/// margin) and, when the shape came from another parent than the magnitude, `mag_parent`.
SampleSummary sample_field(const Morphology& morphology, const FieldGeometry& field,
                           const SampleOptions& options, const std::optional<Tile>& tile,
                           const std::function<void(const ObjectRecord&)>& emit);

/// The field replayed (shapesim-sample --replay): each galaxy model shapesim-decompose fitted on
/// this field's image (`fits`: its shapesim.shapelet/1 records) as an object where it was
/// fitted, with its own coefficients, flux and magnitude — no draw, no rotation. Rendered with
/// new noise and measured like the real image, it pairs every real galaxy with its model (the
/// models' fidelity, apart from what a draw changes). Records carry the fit's id (also as
/// `parent`), its x, y, ra, dec through `field`'s WCS, `frame` (the fit's; "observed" when it
/// has none), `psf_beta` when it has one, `reach` (model_reach plus `margin` pixels) and the
/// fit's bands. Skipped: stars, and fits with no light to draw (flux ≤ 0, no coefficients).
/// Error (the fit's id) when a fit's pixel scale is not the field's (to 1 part in 10⁶: its x, y
/// would not be this field's pixels) or its centre lies further outside the field than its reach;
/// the Error's line is the fit's place in `fits`, from 1 (the caller knows the file's lines).
/// Every fit is checked before the first is emitted: a refused replay emits nothing.
struct ReplaySummary {
    long written = 0, outside_tile = 0, stars = 0, no_light = 0;
};
ReplaySummary replay_field(const std::vector<ShapeletRecord>& fits, const FieldGeometry& field,
                           double margin, const std::optional<Tile>& tile,
                           const std::function<void(const ObjectRecord&)>& emit);

}  // namespace shapesim
