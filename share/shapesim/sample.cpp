#include "shapesim/sample.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/error.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/rng.hpp"
#include "shapesim/text_rows.hpp"
#include "shapesim/transform.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

namespace shapesim {

double StarCounts::magnitude(double u) const {
    if (!bins.empty()) {
        double total = 0.0;
        for (const Bin& b : bins) total += b.count;
        double target = u * total;
        for (const Bin& b : bins) {
            if (target < b.count) return b.lo + (b.hi - b.lo) * (target / b.count);
            target -= b.count;
        }
        return bins.back().hi;
    }
    return power_law_magnitude(u, slope, mag_min, mag_max);
}

void StarCounts::validate() const {
    if (!(density >= 0.0 && std::isfinite(density)))
        throw Error("must be ≥ 0", "", 0, "star_density");
    if (!std::isfinite(slope)) throw Error("must be finite", "", 0, "star_slope");
    if (!(mag_max > mag_min)) throw Error("star magnitude range is empty", "", 0, "star_mag");
    double total = 0.0;
    for (const Bin& b : bins) {
        if (!(b.hi > b.lo) || !(b.count >= 0.0) || !std::isfinite(b.count))
            throw Error("each bin needs lo < hi and a count ≥ 0", "", 0, "star_histogram");
        total += b.count;
    }
    if (!bins.empty() && !(total > 0.0))
        throw Error("the histogram holds no stars", "", 0, "star_histogram");
}

std::optional<StarCounts> field_star_counts(const std::vector<SourceField>& fields,
                                            double mag_limit) {
    std::vector<double> mags;
    double area = 0.0;
    for (const SourceField& f : fields) {
        if (!f.star_mags) continue;
        area += f.area_arcmin2;
        for (const double m : *f.star_mags)
            if (m <= mag_limit) mags.push_back(m);
    }
    if (!(area > 0.0)) return std::nullopt;
    StarCounts counts;
    counts.density = double(mags.size()) / area;
    if (mags.empty()) return counts;
    std::sort(mags.begin(), mags.end());
    const double bin = 0.5;
    const double first = std::floor(mags.front() / bin) * bin;
    for (double lo = first; lo <= mags.back(); lo += bin) {
        const auto n = std::count_if(mags.begin(), mags.end(),
                                     [&](double m) { return m >= lo && m < lo + bin; });
        counts.bins.push_back({lo, std::min(lo + bin, std::max(mag_limit, lo + 1e-9)), double(n)});
    }
    counts.mag_min = counts.bins.front().lo;
    counts.mag_max = counts.bins.back().hi;
    return counts;
}

std::vector<StarCounts::Bin> read_star_histogram(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw Error("cannot open", path);
    std::vector<StarCounts::Bin> bins;
    for_each_text_row(in, path, [&](const std::string& text, long number) {
        std::istringstream fields(text);
        StarCounts::Bin b;
        std::string rest;
        if (!(fields >> b.lo >> b.hi >> b.count) || (fields >> rest))
            throw Error("expected three numbers: mag_lo mag_hi count", path, number);
        if (!(b.hi > b.lo) || !(b.count >= 0.0) || !std::isfinite(b.count))
            throw Error("needs mag_lo < mag_hi and count ≥ 0", path, number);
        bins.push_back(b);
    });
    if (bins.empty()) throw Error("no bins", path);
    return bins;
}

void SampleOptions::validate() const {
    if (!(density >= 0.0 && std::isfinite(density))) throw Error("must be ≥ 0", "", 0, "density");
    if (!std::isfinite(mag_limit)) throw Error("must be finite", "", 0, "mag_limit");
    if (!std::isfinite(zero_point)) throw Error("must be finite", "", 0, "zero_point");
    if (!(margin >= 0.0 && std::isfinite(margin))) throw Error("must be ≥ 0", "", 0, "margin");
    if (cell < 1) throw Error("must be ≥ 1 pixel", "", 0, "cell");
    if (ring < 1 || ring > 1000) throw Error("must be in [1, 1000]", "", 0, "ring");
    if (count && *count % std::uint64_t(ring) != 0)
        throw Error("the galaxy count " + std::to_string(*count) +
                        " is no multiple of the ring's " + std::to_string(ring),
                    "", 0, "ring");
    if (faint_limit && !(std::isfinite(*faint_limit) && *faint_limit > mag_limit))
        throw Error("must be fainter than the magnitude limit", "", 0, "faint_limit");
    if (faint_limit && !faint_counts)
        throw Error("needs the fitted counts (a model that recorded its fields)", "", 0,
                    "faint_limit");
    draw.validate();
    // The star counts matter only when there are stars to draw.
    if (stars.density > 0.0 || (star_count && *star_count > 0)) stars.validate();
}


void apply_model_counts(SampleOptions& options, const Morphology& morphology, CountSource source,
                        bool density_given, const std::string& model_path, const CountModel& law) {
    // Refused before anything is fitted or said.
    options.draw.validate();
    if (options.faint_limit && !(*options.faint_limit > options.mag_limit))
        throw Error("must be fainter than the magnitude limit", "", 0, "faint_limit");
    if (source == CountSource::law) {
        options.draw.counts = law_counts(morphology, options.draw, law, options.mag_limit);
    } else if (source == CountSource::fit) {
        try {
            options.draw.counts = conditional_counts(morphology, options.draw, options.mag_limit);
        } catch (const Error& e) {
            throw Error(e.message() + "; draw with --counts parents", model_path);
        }
    }
    const std::optional<CountModel>& counts = options.draw.counts;
    // The counts' density (a law's needs no field), else the real fields'.
    if (!density_given && (counts || !morphology.source_fields.empty()))
        options.density = counts ? counts->density()
                                 : field_density(morphology.source_fields, options.mag_limit);
    if (!options.faint_limit) return;
    // The unresolved galaxies' counts: the conditional draw's fit, or one made for them over
    // every parent's range, extrapolated past the limit.
    if (morphology.source_fields.empty() && !counts)
        throw Error("--faint-limit needs a model that recorded its fields (shapesim-smooth "
                    "--like, --area or --field) for the counts it extrapolates", model_path);
    CountModel faint;
    if (counts) {
        faint = *counts;
    } else {
        const std::vector<std::size_t> order = magnitude_order(morphology, options.mag_limit);
        if (order.empty()) throw Error("no parent as bright as the magnitude limit", model_path);
        const double bright =
            morphology.points[order.front()].mag - 0.5 * options.draw.max_mag_shift;
        try {
            faint = shapesim::fit_counts(morphology.source_fields, bright, options.mag_limit);
        } catch (const Error& e) {
            throw Error(e.message() + " (for --faint-limit)", model_path);
        }
    }
    faint.bright = options.mag_limit;
    faint.faint = *options.faint_limit;
    options.faint_counts = faint;
}

namespace {

// A uniform position over the field's pixel area.
// A record of object `id` of `kind` at pixel position `p` of the field.
// Band b of a drawn object, in units where the reference band has the simulation's zero point
// `zero_point`: band b's is then zp_b + (zero_point − zp_ref) (zp the real images'), so the
// drawn colours are the real ones. A galaxy's `model` gives its coefficients and flux; a star
// (no model) has magnitude `star_mag` in every band.
BandCoefficients band_part(const Morphology& morphology, std::size_t b, double zero_point,
                           const ShapeletModel* model, double star_mag) {
    double band_zero_point = zero_point;
    const auto& zp = morphology.band_zero_points[b];
    if (zp && morphology.zero_point) band_zero_point = *zp + (zero_point - *morphology.zero_point);
    BandCoefficients part;
    part.band = morphology.bands[b];
    if (model) {
        part.coeffs = model->coeffs;
        part.flux = flux(*model);
        if (*part.flux > 0.0) part.mag = band_zero_point - 2.5 * std::log10(*part.flux);
    } else {
        part.mag = star_mag;
        part.flux = std::pow(10.0, -0.4 * (star_mag - band_zero_point));
    }
    part.extra["zero_point"] = band_zero_point;
    return part;
}

ObjectRecord placed(std::string id, const char* kind, const PixelPosition& p,
                    const FieldGeometry& field) {
    ObjectRecord o;
    o.id = std::move(id);
    o.kind = kind;
    const SkyPosition sky = field.wcs.pixel_to_sky(p.x, p.y);
    o.ra = sky.ra;
    o.dec = sky.dec;
    o.x = p.x;
    o.y = p.y;
    return o;
}

// The field's sky cells: cell × cell field pixels from (0.5, 0.5), the last column and row
// taking what is left; cell c = cy · columns + cx covers [x_lo, x_lo + width) × [y_lo, …).
struct Cells {
    long columns = 1, rows = 1, side = 1;
    const FieldGeometry* field = nullptr;
    Cells(const FieldGeometry& f, long cell)
        : columns((f.nx + cell - 1) / cell), rows((f.ny + cell - 1) / cell), side(cell),
          field(&f) {}
    std::uint64_t count() const { return std::uint64_t(columns * rows); }
    double x_lo(std::uint64_t c) const {
        return 0.5 + double(long(c % std::uint64_t(columns)) * side);
    }
    double y_lo(std::uint64_t c) const {
        return 0.5 + double(long(c / std::uint64_t(columns)) * side);
    }
    double width(std::uint64_t c) const {
        const long x = long(c % std::uint64_t(columns)) * side;
        return double(std::min(side, field->nx - x));
    }
    double height(std::uint64_t c) const {
        const long y = long(c / std::uint64_t(columns)) * side;
        return double(std::min(side, field->ny - y));
    }
    std::uint64_t pixels(std::uint64_t c) const { return std::uint64_t(width(c) * height(c)); }
    double area_arcmin2(std::uint64_t c) const {  // as FieldGeometry::area_arcmin2
        return width(c) * height(c) * field->pixel_scale * field->pixel_scale / 3600.0;
    }
    /// Whether any point of cell c lies within `radius` pixels of the tile.
    bool reaches(std::uint64_t c, const Tile& tile, double radius) const {
        const double x0 = x_lo(c), y0 = y_lo(c), x1 = x0 + width(c), y1 = y0 + height(c);
        const double dx = std::max({double(tile.x0) - 0.5 - x1, 0.0, x0 - double(tile.x1) - 0.5});
        const double dy = std::max({double(tile.y0) - 0.5 - y1, 0.0, y0 - double(tile.y1) - 0.5});
        return dx * dx + dy * dy <= radius * radius;
    }
    /// A uniform position in cell c (over the whole field when it is the only cell).
    PixelPosition position(std::uint64_t c, RandomStream& r) const {
        PixelPosition p;
        p.x = x_lo(c) + width(c) * r.uniform();
        p.y = y_lo(c) + height(c) * r.uniform();
        return p;
    }
};

// Object k of cell c: its stream key and its id ("g17" in cell 0, "g3.17" in cell 3).
std::uint64_t object_key(std::uint64_t cell, std::uint64_t k) { return (cell << 32) | k; }
std::string object_id(const char* prefix, std::uint64_t cell, std::uint64_t k) {
    return prefix +
           (cell == 0 ? std::to_string(k) : std::to_string(cell) + "." + std::to_string(k));
}

// Each cell's number of objects: Poisson(density × its area) from RandomStream(seed, cell,
// `purpose`), or an exact total shared out in proportion to the cells' areas (largest
// remainders, ties to the lower cell).
std::vector<std::uint64_t> cell_counts(const Cells& cells, std::uint64_t seed, double density,
                                       const std::optional<std::uint64_t>& total,
                                       const char* purpose) {
    const std::uint64_t n = cells.count();
    require(n < (std::uint64_t(1) << 32), "more than 2^32 sky cells: give a larger --cell");
    std::vector<std::uint64_t> counts(n, 0);
    if (!total) {
        for (std::uint64_t c = 0; c < n; ++c) {
            RandomStream r(seed, c, purpose);
            counts[c] = r.poisson(density * cells.area_arcmin2(c));
            require(counts[c] < (std::uint64_t(1) << 32), "more than 2^32 objects in a sky cell");
        }
        return counts;
    }
    // In whole pixels, so the shares are exact: cell c gets ⌊T · p_c / P⌋ and the remainders
    // T · p_c mod P decide who gets the rest.
    unsigned __int128 pixels = 0;
    for (std::uint64_t c = 0; c < n; ++c) pixels += cells.pixels(c);
    std::vector<std::pair<unsigned __int128, std::uint64_t>> remainders;
    std::uint64_t given = 0;
    for (std::uint64_t c = 0; c < n; ++c) {
        const unsigned __int128 product = (unsigned __int128)(*total) * cells.pixels(c);
        counts[c] = std::uint64_t(product / pixels);
        given += counts[c];
        remainders.push_back({product % pixels, c});
    }
    std::stable_sort(remainders.begin(), remainders.end(),
                     [](const auto& a, const auto& b) { return a.first > b.first; });
    for (std::size_t i = 0; given < *total; ++i, ++given) ++counts[remainders[i].second];
    for (const std::uint64_t count : counts)
        require(count < (std::uint64_t(1) << 32), "more than 2^32 objects in a sky cell");
    return counts;
}

}  // namespace

namespace {

// No galaxy reaches further than the widest parent, perturbed, at the top order: a tile
// skips the shape draw of objects beyond that bound (pixels, with the margin).
// A shape moved to another magnitude is scaled by 10^{−0.4 s (m − m_parent)}, m within
// [brightest parent − its λ_mag (conditional: or its gap; fitted counts: their bright end),
// mag_limit].
double galaxy_reach_bound(const Morphology& morphology, const DrawOptions& draw,
                          const SampleOptions& options, double scale) {
    const bool conditional = draw.neighbours > 0 && !morphology.lambda.is_delta();
    double brightest = draw.counts ? draw.counts->bright : options.mag_limit;
    for (const auto& p : morphology.points) {
        if (!(p.weight > 0.0) || draw.counts) continue;
        const double spread = conditional ? conditional_mag_spread(p, morphology.lambda.mag, draw)
                                          : morphology.lambda.mag;
        brightest = std::min(brightest, p.mag - spread);
    }
    double beta_max = 0.0;
    for (const auto& p : morphology.points) {
        double scale_up = 1.0;
        if (conditional)
            scale_up =
                std::max(std::pow(10.0, -0.4 * draw.size_slope * (brightest - p.mag)),
                         std::pow(10.0, -0.4 * draw.size_slope * (options.mag_limit - p.mag)));
        beta_max = std::max(beta_max, p.beta * scale_up);
    }
    if ((conditional || options.faint_limit) && draw.mix >= 2) {
        // A mixture's β is at most the largest parent radius (moved to the brightest magnitude)
        // over the smallest parent radius in units of β.
        double radius = 0.0, size = std::numeric_limits<double>::infinity();
        for (const auto& p : morphology.points) {
            if (!std::isfinite(p.size2)) continue;
            const double up = std::pow(10.0, -0.4 * draw.size_slope * (brightest - p.mag));
            const double down =
                std::pow(10.0, -0.4 * draw.size_slope * (options.mag_limit - p.mag));
            radius = std::max(radius, p.beta * std::sqrt(p.size2) * std::max(up, down));
            size = std::min(size, std::sqrt(p.size2));
        }
        if (radius > 0.0) beta_max = std::max(beta_max, radius / size);
    }
    return model_reach((beta_max + morphology.lambda.beta) / scale, morphology.n_max) +
           options.margin;
}

// The record of drawn galaxy `g`, object `j` of `cell`, at `p`, reaching `reach` pixels.
ObjectRecord galaxy_record(const Morphology& morphology, const DrawnGalaxy& g, std::uint64_t cell,
                           std::uint64_t j, const PixelPosition& p, const FieldGeometry& field,
                           const SampleOptions& options, double reach) {
    ObjectRecord o = placed(object_id("g", cell, j), "galaxy", p, field);
    o.mag = g.mag;
    o.flux = g.flux;
    o.beta = g.beta;
    o.pixel_scale = field.pixel_scale;
    o.n_max = g.model.n_max;
    o.coeffs = g.model.coeffs;
    o.parent = morphology.points[g.parent].id;
    o.extra["rotation"] = g.rotation / degree;
    o.extra["reflected"] = g.reflected;
    o.extra["perturbation"] = g.perturbation;
    o.extra["frame"] = morphology.frame;  // render refuses to convolve an observed one twice
    if (morphology.points[g.parent].psf_beta > 0.0)
        o.extra["psf_beta"] = morphology.points[g.parent].psf_beta;
    if (g.mag_parent != g.parent) o.extra["mag_parent"] = morphology.points[g.mag_parent].id;
    if (!g.parents.empty()) {
        Json ids = Json::array(), weights = Json::array();
        for (std::size_t j = 0; j < g.parents.size(); ++j) {
            ids.push_back(morphology.points[g.parents[j]].id);
            weights.push_back(g.weights[j]);
        }
        o.extra["parents"] = std::move(ids);
        o.extra["weights"] = std::move(weights);
    }
    o.extra["reach"] = reach;
    for (std::size_t b = 0; b < g.band_models.size(); ++b)
        o.bands.push_back(band_part(morphology, b, options.zero_point, &g.band_models[b], 0.0));
    return o;
}

// Object j of every cell a tile reaches (all cells without a tile), with its key and its
// position from the stream of (seed, key, `where`), when the position lies within
// `reach_bound` of the tile: visit(cell, j, key, position). Returns the cells read.
template <class Visit>
std::uint64_t for_each_placed(const Cells& cells, const std::vector<std::uint64_t>& counts,
                              std::uint64_t seed, const char* where,
                              const std::optional<Tile>& tile, double reach_bound, Visit&& visit) {
    std::uint64_t read = 0;
    for (std::uint64_t cell = 0; cell < cells.count(); ++cell) {
        if (tile && !cells.reaches(cell, *tile, reach_bound)) continue;  // a tile reads its cells
        ++read;
        for (std::uint64_t j = 0; j < counts[cell]; ++j) {
            const std::uint64_t k = object_key(cell, j);
            RandomStream stream(seed, k, where);
            const PixelPosition p = cells.position(cell, stream);
            if (tile && !tile->reaches(p.x, p.y, reach_bound)) continue;
            visit(cell, j, k, p);
        }
    }
    return read;
}

// Galaxies drawn from a count law (CountModel::tabulated) come in fixed 0.5-mag slices from
// the law's bright end: each cell's count in slice s is Poisson from the stream of (seed,
// object_key(cell, s), "galaxy count slice"), its objects numbered after the brighter slices' and their magnitudes drawn within
// it; the slice holding the limit is drawn whole and its galaxies past the limit dropped. So
// a galaxy brighter than any limit is the same galaxy (id, magnitude, place, shape) whatever
// the limit: the counts do not move with --mag-limit.
struct LawSlices {
    static constexpr double width = 0.5;
    std::vector<double> edges;                        ///< slice s is [edges[s], edges[s + 1])
    std::vector<DrawOptions> draws;                   ///< the draw with its slice's counts
    std::vector<std::vector<std::uint64_t>> starts;   ///< per cell, each slice's first object
    std::vector<std::uint64_t> totals;                ///< per cell, objects of every slice
    const Cells* cells = nullptr;
    std::uint64_t seed = 0;

    LawSlices(const DrawOptions& draw, const SampleOptions& options, const Cells& c)
        : cells(&c), seed(options.seed) {
        const CountModel& law = *draw.counts;
        for (int s = 0;; ++s) {
            edges.push_back(law.bright + width * s);
            if (edges.back() >= options.mag_limit) break;
        }
        // A --density given scales the law; the law's own density otherwise.
        const double scale = options.density / law.density(law.bright, options.mag_limit);
        const std::uint64_t ring = std::uint64_t(options.ring);
        for (std::size_t s = 0; s + 1 < edges.size(); ++s) {
            DrawOptions d = draw;
            d.counts->bright = edges[s];
            d.counts->faint = edges[s + 1];
            draws.push_back(d);
        }
        starts.assign(c.count(), {});
        totals.assign(c.count(), 0);
        for (std::uint64_t cell = 0; cell < c.count(); ++cell)
            for (std::size_t s = 0; s < draws.size(); ++s) {
                RandomStream r(seed, object_key(cell, s), "galaxy count slice");
                const double mean = scale * draws[s].counts->density() * c.area_arcmin2(cell);
                starts[cell].push_back(totals[cell]);
                totals[cell] += r.poisson(mean / double(ring)) * ring;
                require(totals[cell] < (std::uint64_t(1) << 32),
                        "more than 2^32 objects in a sky cell");
            }
    }
    double faint(std::size_t s) const { return edges[s + 1]; }
    std::size_t slice_of(std::uint64_t cell, std::uint64_t j) const {
        const std::vector<std::uint64_t>& st = starts[cell];
        return std::size_t(std::upper_bound(st.begin(), st.end(), j) - st.begin()) - 1;
    }
    // The galaxies of the whole field within the limit: every slice's but the last, whose
    // magnitudes (the first deviate of each ring's stream, as the draw takes it) are checked.
    std::uint64_t within_limit(const SampleOptions& options) const {
        const std::uint64_t ring = std::uint64_t(options.ring);
        std::uint64_t n = 0;
        const std::size_t last = draws.size() - 1;
        for (std::uint64_t cell = 0; cell < cells->count(); ++cell) {
            n += starts[cell][last];
            for (std::uint64_t j = starts[cell][last]; j < totals[cell]; j += ring) {
                RandomStream stream(seed, object_key(cell, j), "galaxy");
                if (draws[last].counts->magnitude(stream.uniform()) <= options.mag_limit)
                    n += ring;
            }
        }
        return n;
    }
};

// The galaxies below the magnitude limit (SampleOptions::faint_limit), each cell's after its
// galaxies, keyed apart from them: a field drawn with them holds the same galaxies as without.
void sample_faint(const Morphology& morphology, const FieldGeometry& field,
                  const SampleOptions& options, const std::optional<Tile>& tile,
                  const Cells& cells, const DrawOptions& draw, double reach_bound,
                  const std::function<void(const ObjectRecord&)>& emit, SampleSummary& summary) {
    if (!options.faint_limit || !options.faint_counts) return;
    DrawOptions faint = draw;
    faint.counts = options.faint_counts;
    const std::vector<std::uint64_t> counts = cell_counts(
        cells, options.seed, options.faint_counts->density(), std::nullopt, "faint galaxy count");
    for (const std::uint64_t n : counts) summary.faint += n;
    for_each_placed(cells, counts, options.seed, "faint galaxy position", tile, reach_bound,
                    [&](std::uint64_t cell, std::uint64_t j, std::uint64_t k,
                        const PixelPosition& p) {
        RandomStream stream(options.seed, k, "faint galaxy");
        const DrawnGalaxy g =
            draw_faint_galaxy(morphology, stream, field.pixel_scale, options.zero_point, faint);
        const double reach = model_reach(g.model.beta_pix, g.model.n_max) + options.margin;
        if (tile && !tile->reaches(p.x, p.y, reach)) return;
        ObjectRecord o = galaxy_record(morphology, g, cell, j, p, field, options, reach);
        o.id = object_id("u", cell, j);
        o.extra["below_limit"] = true;
        emit(o);
        ++summary.faint_out;
    });
}

// Stars: the PSF at a magnitude from the star counts, each cell's after the galaxies.
void sample_stars(const Morphology& morphology, const FieldGeometry& field,
                  const SampleOptions& options, const std::optional<Tile>& tile,
                  const Cells& cells, const std::function<void(const ObjectRecord&)>& emit,
                  SampleSummary& summary) {
    const std::vector<std::uint64_t> stars =
        cell_counts(cells, options.seed, options.stars.density, options.star_count, "star count");
    for (const std::uint64_t n : stars) summary.stars += n;
    for (std::uint64_t cell = 0; cell < cells.count(); ++cell) {
        if (tile && !cells.reaches(cell, *tile, options.margin)) continue;
        for (std::uint64_t j = 0; j < stars[cell]; ++j) {
            const std::uint64_t k = object_key(cell, j);
            RandomStream where(options.seed, k, "star position");
            const PixelPosition p = cells.position(cell, where);
            if (tile && !tile->reaches(p.x, p.y, options.margin)) continue;
            RandomStream stream(options.seed, k, "star");
            ObjectRecord o = placed(object_id("s", cell, j), "star", p, field);
            o.mag = options.stars.magnitude(stream.uniform());
            o.flux = std::pow(10.0, -0.4 * (*o.mag - options.zero_point));
            o.extra["reach"] = options.margin;
            // Multi-band: a flat spectrum (AB colour 0); star colours are not modelled.
            for (std::size_t b = 0; b < morphology.bands.size(); ++b)
                o.bands.push_back(band_part(morphology, b, options.zero_point, nullptr, *o.mag));
            emit(o);
            ++summary.stars_out;
        }
    }
}

}  // namespace

std::string SampleSummary::describe(const FieldGeometry& field, double density,
                                    bool in_tile) const {
    std::ostringstream line;
    line << galaxies << " galaxies and " << stars << " stars over " << field.area_arcmin2()
         << " arcmin^2 (" << density << " per arcmin^2; " << field.nx << " x " << field.ny
         << " pixels); " << galaxies_out << " galaxies and " << stars_out << " stars written"
         << (in_tile ? " (in the tile)" : "") << " from " << cells_read << " of " << cells
         << " sky cells; " << redraws << " perturbations redrawn; ";
    if (faint > 0)
        line << faint << " galaxies below the limit (" << faint_out << " written); ";
    return line.str();
}

SampleSummary sample_field(const Morphology& morphology, const FieldGeometry& field,
                           const SampleOptions& options, const std::optional<Tile>& tile,
                           const std::function<void(const ObjectRecord&)>& emit) {
    options.validate();
    require(field.nx > 0 && field.ny > 0 && field.pixel_scale > 0.0, "the field is empty");
    SampleSummary summary;
    const double scale = field.pixel_scale;

    // Galaxies.
    const std::vector<double> parents = parent_table(morphology, options.mag_limit);
    DrawOptions draw = options.draw;
    draw.by_magnitude = magnitude_order(morphology, options.mag_limit);
    const Cells cells(field, options.cell);
    // Rings: whole rings per cell, the copies of one draw keyed by the ring's first object.
    const std::uint64_t ring = std::uint64_t(options.ring);
    const std::optional<LawSlices> slices =
        draw.counts && draw.counts->tabulated() && !options.count
            ? std::optional(LawSlices(draw, options, cells))
            : std::nullopt;
    std::vector<std::uint64_t> galaxies;
    if (slices) {
        galaxies = slices->totals;
        summary.galaxies = slices->within_limit(options);
    } else {
        galaxies = cell_counts(cells, options.seed, options.density / double(ring),
                               options.count ? std::optional(*options.count / ring) : std::nullopt,
                               "galaxy count");
        for (std::uint64_t& n : galaxies) n *= ring;
        for (const std::uint64_t n : galaxies) summary.galaxies += n;
    }
    const double reach_bound = galaxy_reach_bound(morphology, draw, options, scale);
    summary.cells = cells.count();
    summary.cells_read = for_each_placed(
        cells, galaxies, options.seed, "galaxy position", tile, reach_bound,
        [&](std::uint64_t cell, std::uint64_t j, std::uint64_t k, const PixelPosition& p) {
            // A slice's rings start at multiples of `ring`: members stay in one slice.
            const std::uint64_t member = j % ring;
            RandomStream stream(options.seed, ring > 1 ? object_key(cell, j - member) : k,
                                "galaxy");
            const std::size_t slice = slices ? slices->slice_of(cell, j) : 0;
            DrawnGalaxy g =
                slices ? draw_galaxy(morphology, parents, stream, scale, options.zero_point,
                                     slices->faint(slice), slices->draws[slice])
                       : draw_galaxy(morphology, parents, stream, scale, options.zero_point,
                                     options.mag_limit, draw);
            if (g.mag > options.mag_limit) return;  // the last slice, past the limit
            const double reach = model_reach(g.model.beta_pix, g.model.n_max) + options.margin;
            if (tile && !tile->reaches(p.x, p.y, reach)) return;
            if (member > 0) {  // turned by member·π/ring: its ellipticity by 2π member/ring
                const double turn = pi * double(member) / double(ring);
                g.model = rotate(g.model, turn);
                for (ShapeletModel& b : g.band_models) b = rotate(b, turn);
                g.rotation += turn;
            }
            summary.redraws += member == 0 ? std::uint64_t(g.redraws) : 0;
            ObjectRecord o = galaxy_record(morphology, g, cell, j, p, field, options, reach);
            if (ring > 1) {
                // Where the ring's first copy is: a ring shares one lensing (shapesim-lens
                // evaluates it there), and a tile may hold some copies without the first.
                PixelPosition first = p;
                if (member > 0) {
                    RandomStream at(options.seed, object_key(cell, j - member), "galaxy position");
                    first = cells.position(cell, at);
                }
                o.extra["ring"] = {{"first", object_id("g", cell, j - member)},
                                   {"member", member},
                                   {"of", ring},
                                   {"x", first.x},
                                   {"y", first.y}};
            }
            emit(o);
            ++summary.galaxies_out;
        });
    sample_faint(morphology, field, options, tile, cells, draw, reach_bound, emit, summary);
    sample_stars(morphology, field, options, tile, cells, emit, summary);
    return summary;
}

ParentShares::ParentShares(std::vector<double> mag_limits)
    : limits_(std::move(mag_limits)), counts_(limits_.size()) {}

void ParentShares::add(const ObjectRecord& record) {
    if (record.kind != "galaxy" || !record.mag || !record.parent) return;
    for (std::size_t k = 0; k < limits_.size(); ++k)
        if (*record.mag < limits_[k]) ++counts_[k][*record.parent];
}

std::vector<ParentShares::Share> ParentShares::shares() const {
    std::vector<Share> out;
    for (std::size_t k = 0; k < limits_.size(); ++k) {
        Share s;
        s.mag_limit = limits_[k];
        for (const auto& [parent, n] : counts_[k]) {
            s.galaxies += n;
            if (n > s.largest) {
                s.largest = n;
                s.parent = parent;
            }
        }
        out.push_back(s);
    }
    return out;
}

std::string ParentShares::summary(const std::string& band) const {
    std::ostringstream text;
    for (const Share& s : shares()) {
        if (text.tellp() > 0) text << "; ";
        text << band << " < " << s.mag_limit << ": " << s.largest << "/" << s.galaxies;
        if (s.largest > 0) text << " from " << s.parent;
    }
    return text.str();
}

ReplaySummary replay_field(const std::vector<ShapeletRecord>& fits, const FieldGeometry& field,
                           double margin, const std::optional<Tile>& tile,
                           const std::function<void(const ObjectRecord&)>& emit) {
    ReplaySummary summary;
    // Every fit is checked before any is written: a refused replay writes nothing.
    std::vector<ObjectRecord> objects;
    for (std::size_t k = 0; k < fits.size(); ++k) {
        const ShapeletRecord& fit = fits[k];
        const long number = long(k) + 1;  // the Error's line: the fit's place in `fits`
        const auto kind = fit.extra.find("kind");
        if (kind != fit.extra.end() && *kind == "star") {
            ++summary.stars;
            continue;
        }
        if (fit.coeffs.empty() || !fit.flux || !(*fit.flux > 0.0)) {
            ++summary.no_light;
            continue;
        }
        if (!(std::abs(fit.pixel_scale / field.pixel_scale - 1.0) <= 1e-6)) {
            std::ostringstream why;
            why << "fit " << fit.id << " is at " << fit.pixel_scale << "\"/pixel, the field at "
                << field.pixel_scale << "\": replay the fits on the image they were made of "
                   "(--like that image)";
            throw Error(why.str(), "", number, "pixel_scale");
        }
        // An edge galaxy's fit may be centred just off the image, never beyond its own reach.
        const double reach = model_reach(fit.beta / fit.pixel_scale, fit.n_max) + margin;
        if (!(fit.x >= 0.5 - reach && fit.x <= field.nx + 0.5 + reach && fit.y >= 0.5 - reach &&
              fit.y <= field.ny + 0.5 + reach)) {
            std::ostringstream why;
            why << "fit " << fit.id << " is centred at (" << fit.x << ", " << fit.y
                << "), outside the " << field.nx << " x " << field.ny
                << " field: replay the fits on the image they were made of (--like that image)";
            throw Error(why.str(), "", number, "x");
        }
        if (tile && !tile->reaches(fit.x, fit.y, reach)) {
            ++summary.outside_tile;
            continue;
        }
        ObjectRecord o = placed(fit.id, "galaxy", {fit.x, fit.y}, field);
        o.mag = fit.mag;
        o.flux = *fit.flux;
        o.beta = fit.beta;
        o.pixel_scale = fit.pixel_scale;  // the coefficients' own units
        o.n_max = fit.n_max;
        o.coeffs = fit.coeffs;
        o.parent = fit.id;
        const auto frame = fit.extra.find("frame");
        o.extra["frame"] = frame != fit.extra.end() ? *frame : Json("observed");
        if (const auto psf_beta = fit.extra.find("psf_beta"); psf_beta != fit.extra.end())
            o.extra["psf_beta"] = *psf_beta;
        o.extra["reach"] = reach;
        o.bands = fit.bands;
        objects.push_back(std::move(o));
    }
    for (const ObjectRecord& o : objects) emit(o);
    summary.written = long(objects.size());
    return summary;
}

}  // namespace shapesim
