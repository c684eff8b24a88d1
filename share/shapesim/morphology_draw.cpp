// New galaxies from the morphology PDF (morphology.hpp, paper §3): the parents' table and
// magnitude order, mixtures of aligned neighbours, the paper's perturbed draw, faint galaxies.
#include "shapesim/morphology.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/deconvolution.hpp"
#include "shapesim/error.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/positivity.hpp"
#include "shapesim/render.hpp"
#include "shapesim/transform.hpp"
#include "shapesim/version.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>

namespace shapesim {

std::vector<double> parent_table(const Morphology& morphology, double mag_limit) {
    std::vector<double> cumulative;
    double sum = 0.0;
    for (const auto& p : morphology.points) {
        if (p.mag <= mag_limit) sum += p.weight;
        cumulative.push_back(sum);
    }
    if (!(sum > 0.0))
        throw Error("no model with positive weight is as bright as the magnitude limit");
    return cumulative;
}

namespace {

// The packed (n, m) sequence up to the largest order a record may hold; every smaller order's
// sequence is its prefix (the packing runs over n). Built once, shared by all threads.
const std::vector<PolarIndex>& packed_indices() {
    static const std::vector<PolarIndex> table = polar_indices(100);
    return table;
}

}  // namespace

void DrawOptions::validate() const {
    if (neighbours < 0) throw Error("must be ≥ 0", "", 0, "neighbours");
    if (!std::isfinite(size_slope)) throw Error("must be finite", "", 0, "size_slope");
    if (!(max_mag_shift >= 0.0)) throw Error("must be ≥ 0", "", 0, "max_mag_shift");
    if (!(max_perturbation > 0.0)) throw Error("must be > 0", "", 0, "max_perturbation");
    if (!(hole_allowance >= 0.0)) throw Error("must be ≥ 0", "", 0, "hole_allowance");
    if (mix < 0 || mix > 64) throw Error("must be in [0, 64]", "", 0, "mix");
    if (mix >= 2 && neighbours > 0 && neighbours < mix)
        throw Error("a mixture of " + std::to_string(mix) + " parents needs neighbours ≥ " +
                        std::to_string(mix),
                    "", 0, "mix");
}

std::vector<std::size_t> magnitude_order(const Morphology& morphology, double mag_limit) {
    std::vector<std::size_t> order;
    for (std::size_t k = 0; k < morphology.points.size(); ++k)
        if ((morphology.points[k].weight > 0.0 || morphology.points[k].shape_only) &&
            morphology.points[k].mag <= mag_limit)
            order.push_back(k);
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
        return morphology.points[a].mag < morphology.points[b].mag;
    });
    return order;
}

double conditional_mag_spread(const MorphologyPoint& p, double lambda_mag,
                              const DrawOptions& draw) {
    const double gap = std::isfinite(p.mag_gap) ? p.mag_gap : 0.0;
    return std::max(lambda_mag, std::min(gap, 0.5 * draw.max_mag_shift));
}

namespace {

// The window [lo, hi) of `order` (sorted by magnitude) holding the `k` parents nearest in
// magnitude to `mag` that lie within `max_shift` of it (the nearest always qualifies). A draw
// brighter than every parent takes the window of the brightest: the k brightest parents (within
// max_shift of the brightest), each moved up along the size–magnitude relation, so the bright
// end is many galaxies, not copies of the one brightest.
std::pair<std::size_t, std::size_t> magnitude_window(const Morphology& morphology,
                                                     const std::vector<std::size_t>& order,
                                                     double mag, std::size_t k, double max_shift) {
    k = std::min(k, order.size());
    const auto at = [&](std::size_t i) { return morphology.points[order[i]].mag; };
    if (!order.empty()) mag = std::max(mag, at(0));
    // [lo, hi) grows from the insertion point towards the nearer side, ties to the brighter.
    std::size_t hi = std::size_t(
        std::lower_bound(order.begin(), order.end(), mag,
                         [&](std::size_t p, double m) { return morphology.points[p].mag < m; }) -
        order.begin());
    std::size_t lo = hi;
    while (hi - lo < k) {
        if (lo == 0) ++hi;
        else if (hi == order.size()) --lo;
        else if (mag - at(lo - 1) <= at(hi) - mag) --lo;
        else ++hi;
    }
    while (hi - lo > 1 && std::max(mag - at(lo), at(hi - 1) - mag) > max_shift) {
        if (mag - at(lo) > at(hi - 1) - mag) ++lo;
        else --hi;
    }
    return {lo, hi};
}

// One parent of the window about `mag`, chosen uniformly by the deviate u.
std::size_t near_in_magnitude(const Morphology& morphology, const DrawOptions& draw, double mag,
                              double u) {
    const std::vector<std::size_t>& order = draw.by_magnitude;
    const auto [lo, hi] = magnitude_window(morphology, order, mag, std::size_t(draw.neighbours),
                                           draw.max_mag_shift);
    const std::size_t k = hi - lo;
    return order[lo + std::min(k - 1, std::size_t(u * double(k)))];
}

}  // namespace

std::optional<CountModel> conditional_counts(const Morphology& morphology, const DrawOptions& draw,
                                             double mag_limit) {
    if (draw.neighbours <= 0 || morphology.lambda.is_delta() || morphology.source_fields.empty())
        return std::nullopt;
    const std::vector<std::size_t> order = magnitude_order(morphology, mag_limit);
    if (order.empty()) return std::nullopt;
    const double bright = morphology.points[order.front()].mag - 0.5 * draw.max_mag_shift;
    return fit_counts(morphology.source_fields, bright, mag_limit);
}

std::optional<CountModel> law_counts(const Morphology& morphology, const DrawOptions& draw,
                                     const CountModel& law, double mag_limit) {
    if (draw.neighbours <= 0 || morphology.lambda.is_delta()) return std::nullopt;
    if (!(mag_limit > law.bright))
        throw Error("the magnitude limit " + std::to_string(mag_limit) +
                    " is not fainter than the count law's bright end " +
                    std::to_string(law.bright));
    CountModel counts = law;
    counts.faint = mag_limit;
    return counts;
}

namespace {

// A parent's shape c, perturbed: every coefficient by the Epanechnikov kernel of its smoothing
// length times `shrink` (m = 0 in value, m > 0 in modulus and phase; in δ mode the draws are
// made and c kept bit for bit), with the flux sum Σ_{n even} c'_{n,0} and ‖c' − c‖², ‖c‖².
struct PerturbedShape {
    std::vector<Complex> shape;
    double sum = 0.0, change = 0.0, norm = 0.0;
};
PerturbedShape perturb_shape(const MorphologyPoint& p, const SmoothingLengths& l, double shrink,
                             RandomStream& stream) {
    const PolarIndex* index = packed_indices().data();
    const bool delta = l.is_delta();
    const double lambda_phase = l.phase_deg * degree;
    const std::size_t count = p.shape.size();
    const bool prepared = p.modulus.size() == count && p.phase.size() == count;
    PerturbedShape out;
    out.shape.assign(count, Complex(0.0, 0.0));
    out.shape[0] = 1.0;
    out.sum = 1.0;
    for (std::size_t k = 0; k < count; ++k) {
        const Complex c = p.shape[k];
        out.norm += std::norm(c);
        if (k == 0) continue;
        if (index[k].m == 0) {
            out.shape[k] =
                Complex(c.real() + shrink * l.coefficient[k] * stream.epanechnikov(), 0.0);
            if (index[k].n % 2 == 0) out.sum += out.shape[k].real();
        } else {
            const double modulus = (prepared ? p.modulus[k] : std::abs(c)) +
                                   shrink * l.coefficient[k] * stream.epanechnikov();
            const double phase = (prepared ? p.phase[k] : std::arg(c)) +
                                 shrink * lambda_phase * stream.epanechnikov();
            out.shape[k] = delta ? c : std::polar(modulus, phase);
        }
        out.change += std::norm(out.shape[k] - c);
    }
    return out;
}

// The parent's own shape, unperturbed.
PerturbedShape unperturbed(const MorphologyPoint& p) {
    const PolarIndex* index = packed_indices().data();
    PerturbedShape out;
    out.shape = p.shape;
    for (std::size_t k = 0; k < out.shape.size(); ++k) {
        out.norm += std::norm(out.shape[k]);
        if (index[k].m == 0 && index[k].n % 2 == 0) out.sum += out.shape[k].real();
    }
    return out;
}

// Whether a perturbed shape of parent `p`, drawn at `mag` and `beta`, rings no deeper than the
// parent does: the parent's own holes are allowed at the depth (in flux) they had, so a shape
// drawn brighter or more compact than its parent keeps them shallower relative to its peak.
bool rings_no_deeper(const std::vector<Complex>& shape, const MorphologyPoint& p, double mag,
                     double beta, double allowance) {
    ShapeletModel candidate(0.0, 0.0, 1.0, p.n_max);
    candidate.coeffs = shape;
    const double peak_ratio =
        std::pow(10.0, -0.4 * (mag - p.mag)) * (p.beta / beta) * (p.beta / beta);
    return hole_depth(candidate) <= p.hole / std::max(peak_ratio, 1.0) + allowance;
}

// The aligned shape placed: a_{n,m} = a_{0,0} c_{n,m}, reflected about x (a → conj a), then
// rotated by ρ (a_{n,m} → a_{n,m} e^{−imρ}): one complex exponential per coefficient.
ShapeletModel placed_model(const std::vector<Complex>& shape, int n_max, double beta_pix,
                           double a00, double rotation, bool reflected) {
    const PolarIndex* index = packed_indices().data();
    std::vector<Complex> turn(std::size_t(n_max) + 1);  // e^{−imρ} by powers
    const Complex step = std::polar(1.0, -rotation);
    turn[0] = 1.0;
    for (std::size_t m = 1; m < turn.size(); ++m) turn[m] = turn[m - 1] * step;
    ShapeletModel model(0.0, 0.0, beta_pix, n_max);
    for (std::size_t k = 0; k < shape.size(); ++k) {
        const int m = index[k].m;
        if (m == 0) {
            model.coeffs[k] = a00 * shape[k];
        } else {
            const Complex placed = reflected ? std::conj(shape[k]) : shape[k];
            model.coeffs[k] = a00 * placed * turn[std::size_t(m)];
        }
    }
    return model;
}

// The colour kernel (see the header): every band's drawn flux ratio from the parent's,
// the reference's its own; none when colours are not perturbed (δ, no reference band, h = 0).
std::vector<double> drawn_ratios(const Morphology& m, const std::vector<double>& parent,
                                 RandomStream& stream) {
    const double h = m.lambda.colour;
    const Eigen::Index n = Eigen::Index(m.bands.size());
    if (!(h > 0.0) || !m.reference_band || m.colour_root.rows() != n) return {};
    Eigen::VectorXd g(n);
    for (Eigen::Index b = 0; b < n; ++b) g(b) = stream.gaussian();
    const Eigen::VectorXd kick = h * (m.colour_root * g);
    const double shrink = 1.0 / std::sqrt(1.0 + h * h);
    std::vector<double> out(m.bands.size());
    for (std::size_t b = 0; b < out.size(); ++b) {
        const double own = parent[b], mean = m.colour_mean[b];
        out[b] = b == *m.reference_band
                     ? own
                     : std::max(0.0, mean + (own - mean + kick(Eigen::Index(b))) * shrink);
    }
    return out;
}

// The parent of a cumulative-weight table `parents` at u ∈ [0, total): the first whose running
// total exceeds u, never one of weight 0.
std::size_t parent_at(const std::vector<double>& parents, double u) {
    std::size_t parent =
        std::size_t(std::upper_bound(parents.begin(), parents.end(), u) - parents.begin());
    parent = std::min(parent, parents.size() - 1);
    while (parent > 0 && parents[parent] == parents[parent - 1]) --parent;  // weight 0
    return parent;
}

// Each band's model of a drawn galaxy: the parent's, plus the reference perturbation at the
// parent's mean colour, then the colour kernel (drawn last: one-band draws are unchanged).
std::vector<ShapeletModel> band_models(const Morphology& morphology,
                                       const MorphologyPoint& shape_parent,
                                       const PerturbedShape& drawn, double beta_pix, double a00,
                                       const DrawnGalaxy& g, RandomStream& stream) {
    const bool delta = morphology.lambda.is_delta();
    std::vector<double> parent_ratios;
    for (std::size_t b = 0; b < shape_parent.band_shapes.size(); ++b) {
        // (A parent's flux sum is > 0: build_morphology's records have flux > 0.)
        const double ratio = flux_ratio(shape_parent, b);
        parent_ratios.push_back(std::isfinite(ratio) ? ratio : 0.0);
    }
    const std::vector<double> ratios = drawn_ratios(morphology, parent_ratios, stream);
    std::vector<ShapeletModel> models;
    for (std::size_t b = 0; b < shape_parent.band_shapes.size(); ++b) {
        const std::vector<Complex>& own = shape_parent.band_shapes[b];
        const double ratio = parent_ratios[b];
        const double change = ratios.empty() ? 0.0 : ratios[b] - ratio;
        std::vector<Complex> band(own.size());
        for (std::size_t k = 0; k < own.size(); ++k)
            band[k] = delta ? own[k]
                            : own[k] + (drawn.shape[k] - shape_parent.shape[k]) * ratio +
                                  change * drawn.shape[k];
        models.push_back(
            placed_model(band, shape_parent.n_max, beta_pix, a00, g.rotation, g.reflected));
    }
    return models;
}

// A mixture (see "Mixtures" in the header): the shape parent `first` and partners near it in
// shape from the magnitude window about `mag`, each at unit flux and unit β, weighted by a
// flat Dirichlet draw; `point` holds the mixed shape (c_{0,0} = 1) and bands.
struct Mixture {
    MorphologyPoint point;
    std::vector<std::size_t> parents;
    std::vector<double> weights;
    double beta = 0.0;  ///< arcsec, at `mag`
};

// ln of a point's rms radius (arcsec) moved to magnitude `mag` by the size–luminosity slope.
double log_radius(const MorphologyPoint& p, double mag, double size_slope) {
    return std::log(p.beta * std::sqrt(p.size2)) -
           0.4 * std::log(10.0) * size_slope * (mag - p.mag);
}

// The image inner product ∫ f g of two shapes at one β (orthonormality: a_{n,−m} = conj a_{n,m}
// counts each m > 0 twice).
double shape_product(const std::vector<Complex>& a, const std::vector<Complex>& b) {
    const PolarIndex* index = packed_indices().data();
    double sum = 0.0;
    for (std::size_t k = 0; k < std::min(a.size(), b.size()); ++k)
        sum += (index[k].m == 0 ? 1.0 : 2.0) * (a[k] * std::conj(b[k])).real();
    return sum;
}

// The partners of `first` (up to M − 1): picked uniformly among the 2(M − 1) points of the
// window whose aligned shapes (at unit β) are most alike to its own, by the cosine of the angle
// between the images, so that a mixture averages galaxies of one kind and keeps the population's
// spread of concentration, asymmetry and clumpiness (ties by magnitude order).
std::vector<std::size_t> mixture_partners(const Morphology& morphology, const DrawOptions& draw,
                                          std::size_t first, double mag, RandomStream& stream) {
    const MorphologyPoint& p0 = morphology.points[first];
    if (!std::isfinite(p0.size2)) return {};
    const auto [lo, hi] = magnitude_window(morphology, draw.by_magnitude, mag,
                                           std::size_t(draw.neighbours), draw.max_mag_shift);
    const double norm0 = std::sqrt(shape_product(p0.shape, p0.shape));
    std::vector<std::pair<double, std::size_t>> near;
    for (std::size_t i = lo; i < hi; ++i) {
        const std::size_t k = draw.by_magnitude[i];
        const MorphologyPoint& q = morphology.points[k];
        if (k == first || !std::isfinite(q.size2)) continue;
        const double cosine = shape_product(q.shape, p0.shape) /
                              (norm0 * std::sqrt(shape_product(q.shape, q.shape)));
        near.emplace_back(1.0 - cosine, k);
    }
    std::stable_sort(near.begin(), near.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    const std::size_t want = std::size_t(std::max(draw.mix, 1)) - 1;
    near.resize(std::min(near.size(), 2 * want));
    std::vector<std::size_t> partners;
    for (std::size_t j = 0; j < want && j < near.size(); ++j) {  // a partial Fisher–Yates
        const std::size_t pick = j + std::size_t(stream.uniform_index(near.size() - j));
        std::swap(near[j], near[pick]);
        partners.push_back(near[j].second);
    }
    return partners;
}

Mixture mix_parents(const Morphology& morphology, const DrawOptions& draw, std::size_t first,
                    double mag, RandomStream& stream) {
    Mixture out;
    out.parents.push_back(first);
    for (std::size_t k : mixture_partners(morphology, draw, first, mag, stream))
        out.parents.push_back(k);
    // A flat Dirichlet (normalised standard exponentials), its largest weight the shape
    // parent's: the mixture is a new galaxy of its parent's kind.
    double total = 0.0;
    for (std::size_t j = 0; j < out.parents.size(); ++j) {
        out.weights.push_back(out.parents.size() == 1 ? 1.0 : -std::log(stream.uniform_open()));
        total += out.weights.back();
    }
    std::swap(out.weights[0], *std::max_element(out.weights.begin(), out.weights.end()));
    MorphologyPoint& mixed = out.point;
    std::size_t count = 0, bands = 0;
    for (std::size_t k : out.parents) {
        const MorphologyPoint& p = morphology.points[k];
        if (p.shape.size() > count) count = p.shape.size(), mixed.n_max = p.n_max;
        bands = std::max(bands, p.band_shapes.size());
    }
    mixed.shape.assign(count, Complex(0.0, 0.0));
    mixed.band_shapes.assign(bands, std::vector<Complex>(count, Complex(0.0, 0.0)));
    double size2 = 0.0;
    for (std::size_t j = 0; j < out.parents.size(); ++j) {
        const MorphologyPoint& p = morphology.points[out.parents[j]];
        out.weights[j] /= total;
        const double w = out.weights[j] / even_sum(p.shape);  // unit flux at unit β
        for (std::size_t k = 0; k < p.shape.size(); ++k) mixed.shape[k] += w * p.shape[k];
        for (std::size_t b = 0; b < p.band_shapes.size(); ++b)
            for (std::size_t k = 0; k < p.band_shapes[b].size(); ++k)
                mixed.band_shapes[b][k] += w * p.band_shapes[b][k];
        size2 += out.weights[j] * p.size2;
    }
    const double c00 = mixed.shape[0].real();  // Σ w_j / Σ_{n even} c_j > 0
    for (Complex& c : mixed.shape) c /= c00;
    for (auto& band : mixed.band_shapes)
        for (Complex& c : band) c /= c00;
    // Each band's flux ratio is the shape parent's (the colour kernel then draws about it): a
    // mixture takes its partners' colour gradients, not an average of their colours, which
    // would narrow the colours' spread.
    const MorphologyPoint& p0 = morphology.points[first];
    const double sum = even_sum(mixed.shape);
    for (std::size_t b = 0; b < mixed.band_shapes.size() && b < p0.band_shapes.size(); ++b) {
        const double own = flux_ratio(p0, b), ratio = even_sum(mixed.band_shapes[b]) / sum;
        if (std::isfinite(own) && ratio > 0.0 && own > 0.0)
            for (Complex& c : mixed.band_shapes[b]) c *= own / ratio;
    }
    // The shape parent's rms radius (at `mag`), so the sizes are the parents'.
    out.beta = out.parents.size() > 1
                   ? std::exp(log_radius(p0, mag, draw.size_slope)) / std::sqrt(size2)
                   : p0.beta * std::pow(10.0, -0.4 * draw.size_slope * (mag - p0.mag));
    return out;
}

// (det Q)^¼: the radius of a shape's area, kept by a shear.
double area_radius(const Moments& m) {
    return std::pow(m.q11 * m.q22 - m.q12 * m.q12, 0.25);
}

// The ellipticity a mixture of a parent fitted as a round Gaussian is given (n_max < 2: a
// faint galaxy whose data held no more than its flux and size, exactly round although the
// galaxy was not): the adaptive ε of a parent drawn uniformly among the resolved ones (n_max ≥ 2)
// of its magnitude window (a Gaussian's unweighted and adaptive ε are one). NaN for a resolved
// shape parent, when the window holds none, and in δ mode (the shapes are kept as they are).
Complex target_ellipticity(const Morphology& morphology, const DrawOptions& draw,
                           std::size_t first, double mag, RandomStream& stream) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const MorphologyPoint& p0 = morphology.points[first];
    if (morphology.lambda.is_delta() || p0.n_max >= 2) return {nan, nan};
    const auto [lo, hi] = magnitude_window(morphology, draw.by_magnitude, mag,
                                           std::size_t(draw.neighbours), draw.max_mag_shift);
    std::vector<std::size_t> resolved;
    for (std::size_t i = lo; i < hi; ++i) {
        const MorphologyPoint& q = morphology.points[draw.by_magnitude[i]];
        if (q.n_max >= 2 && std::isfinite(std::abs(q.adaptive_epsilon))) resolved.push_back(i);
    }
    if (resolved.empty()) return {nan, nan};
    const std::size_t pick = resolved[std::size_t(stream.uniform_index(resolved.size()))];
    return morphology.points[draw.by_magnitude[pick]].adaptive_epsilon;
}

// The mixture sheared so that its ε is `target`: A = S(target) S(−ε), area and centre kept
// (S(−ε) makes it round, S(target) gives it the target's ellipticity; for the aligned, real ε of
// the model's points A is one shear). Every band's shape the same way. Projected to a relative
// truncation error of 10⁻³ (3% of the light: an ε 0.3 Gaussian needs n_max 4, ε 0.6 12) and
// at most n_max 12 or the mixture's own (a mixture's order is paid for in memory by every
// galaxy drawn: a million of them render in 1 GiB), and renormalised to c_{0,0} = 1. False
// when nothing was done (no target, or a projection that is not a galaxy).
bool shear_to(Mixture& mixture, Complex target) {
    MorphologyPoint& mixed = mixture.point;
    ShapeletModel model(0.0, 0.0, 1.0, mixed.n_max);
    model.coeffs = mixed.shape;
    const Complex now = moments(model).epsilon;
    if (!std::isfinite(std::abs(now)) || !std::isfinite(std::abs(target)) ||
        std::abs(target) >= 1.0 || std::abs(target - now) < 1e-9)
        return false;
    const Eigen::Matrix2d a = shear_matrix(target.real(), target.imag()) *
                              shear_matrix(-now.real(), -now.imag());
    ProjectionOptions options;
    options.tolerance = 1e-3;
    options.n_out_max = std::max(mixed.n_max, 12);
    const Projection sheared = affine_transform(model, a, Eigen::Vector2d::Zero(), options);
    // A projection cut short by n_out_max must still be a galaxy (flux and area > 0), else the
    // mixture stays as it was.
    const Moments check = moments(sheared.model);
    const Complex c00 = sheared.model.coeffs[0];
    if (!(c00.real() > 0.0) || !(check.flux > 0.0) ||
        !(check.q11 * check.q22 - check.q12 * check.q12 > 0.0))
        return false;
    options.n_out = sheared.model.n_max;
    const int n_in = mixed.n_max;
    mixed.n_max = sheared.model.n_max;
    mixed.shape = sheared.model.coeffs;
    for (Complex& c : mixed.shape) c /= c00;
    // Each band keeps its flux ratio exactly (the projection's truncation moves it by ~1e-7).
    const double sum_in = even_sum(model.coeffs), sum_out = even_sum(mixed.shape);
    for (auto& band : mixed.band_shapes) {
        ShapeletModel b(0.0, 0.0, 1.0, n_in);
        b.coeffs = band;
        const double ratio = even_sum(band) / sum_in;
        band = affine_transform(b, a, Eigen::Vector2d::Zero(), options).model.coeffs;
        const double out = even_sum(band);
        for (Complex& c : band) c *= out != 0.0 ? ratio * sum_out / out : 1.0 / c00.real();
    }
    return true;
}

// A conditional draw as a mixture: a magnitude (fitted counts, or a parent's smoothed), its
// shape parent near it in magnitude, the mixture, a rotation and a reflection.
DrawnGalaxy draw_mixture(const Morphology& morphology, const std::vector<double>& parents,
                         RandomStream& stream, double pixel_scale, double zero_point,
                         double mag_limit, const DrawOptions& draw) {
    DrawnGalaxy g;
    // The counts' magnitude from the deviate itself: the same whatever parents the limit admits.
    const double deviate = stream.uniform();
    const double u = deviate * parents.back();
    const std::size_t mag_parent = parent_at(parents, u);
    if (draw.counts) {
        g.mag = draw.counts->magnitude(deviate);
    } else {
        const MorphologyPoint& p = morphology.points[mag_parent];
        const double spread = conditional_mag_spread(p, morphology.lambda.mag, draw);
        // Redrawn while fainter than the limit; after 1000 tries, the parent's own magnitude.
        g.mag = p.mag + spread * stream.epanechnikov();
        while (g.mag > mag_limit)
            g.mag = ++g.redraws < 1000 ? p.mag + spread * stream.epanechnikov() : p.mag;
    }
    const std::size_t first = near_in_magnitude(morphology, draw, g.mag, stream.uniform());
    Mixture mixture = mix_parents(morphology, draw, first, g.mag, stream);
    const MorphologyPoint& p0 = morphology.points[first];
    // A round parent's borrowed ε, keeping the parent's area: (det Q)^¼ its own.
    if (shear_to(mixture, target_ellipticity(morphology, draw, first, g.mag, stream))) {
        ShapeletModel unit(0.0, 0.0, 1.0, mixture.point.n_max), own(0.0, 0.0, 1.0, p0.n_max);
        unit.coeffs = mixture.point.shape;
        own.coeffs = p0.shape;
        mixture.beta = p0.beta * std::pow(10.0, -0.4 * draw.size_slope * (g.mag - p0.mag)) *
                       area_radius(moments(own)) / area_radius(moments(unit));
    }
    g.parent = first;  // the shape parent, whose weight is the largest
    g.mag_parent = draw.counts ? g.parent : mag_parent;
    g.parents = mixture.parents;
    g.weights = mixture.weights;
    g.beta = mixture.beta;
    g.flux = std::pow(10.0, -0.4 * (g.mag - zero_point));
    const double beta_pix = g.beta / pixel_scale;
    const PerturbedShape drawn = unperturbed(mixture.point);
    const double a00 = g.flux / (2.0 * std::sqrt(pi) * beta_pix * drawn.sum);
    g.rotation = stream.angle();
    g.reflected = stream.coin();
    g.model = placed_model(drawn.shape, mixture.point.n_max, beta_pix, a00, g.rotation,
                           g.reflected);
    // How far the mixture is from its shape parent: ‖c − c_p‖/‖c_p‖ (both with c_{0,0} = 1).
    const std::vector<Complex>& own = morphology.points[g.parent].shape;
    double change = 0.0, norm = 0.0;
    for (std::size_t k = 0; k < drawn.shape.size(); ++k) {
        const Complex c = k < own.size() ? own[k] : Complex(0.0, 0.0);
        change += std::norm(drawn.shape[k] - c);
        norm += std::norm(c);
    }
    g.perturbation = std::sqrt(change / norm);
    g.band_models = band_models(morphology, mixture.point, drawn, beta_pix, a00, g, stream);
    return g;
}

}  // namespace

DrawnGalaxy draw_galaxy(const Morphology& morphology, const std::vector<double>& parents,
                        RandomStream& stream, double pixel_scale, double zero_point,
                        double mag_limit, const DrawOptions& draw) {
    const SmoothingLengths& l = morphology.lambda;
    const bool delta = l.is_delta();
    const bool conditional = draw.neighbours > 0 && !delta && !draw.by_magnitude.empty();
    if (conditional && draw.mix >= 2)
        return draw_mixture(morphology, parents, stream, pixel_scale, zero_point, mag_limit, draw);
    DrawnGalaxy g;
    const double deviate = stream.uniform();
    const double u = deviate * parents.back();
    g.parent = parent_at(parents, u);
    // Magnitudes from the fitted counts: drawn once (the same deviate), the shape parent the
    // only parent.
    const bool counted = conditional && draw.counts.has_value();
    if (counted) {
        g.mag = draw.counts->magnitude(deviate);
        g.parent = near_in_magnitude(morphology, draw, g.mag, stream.uniform());
    }
    g.mag_parent = g.parent;
    const MorphologyPoint& first = morphology.points[g.parent];
    // The size–luminosity relation moves a shape's β with its magnitude.
    const auto scaled_beta = [&](const MorphologyPoint& p, double mag) {
        return p.beta * std::pow(10.0, -0.4 * draw.size_slope * (mag - p.mag));
    };
    PerturbedShape drawn;
    double beta = first.beta, mag = first.mag;
    constexpr int max_redraws = 1000, hole_redraws = 500;
    bool shape_chosen = false;
    for (;; ++g.redraws) {
        const MorphologyPoint* p = &first;
        if (g.redraws == max_redraws) {  // give up perturbing: the parent itself
            g.parent = g.mag_parent;
            mag = counted ? g.mag : first.mag;
            beta = counted ? scaled_beta(first, mag) : first.beta;
            drawn = unperturbed(first);
            break;
        }
        if (counted) {
            mag = g.mag;
            beta = scaled_beta(*p, mag) + l.beta * stream.epanechnikov();
        } else if (conditional) {
            // The shape parent is chosen once, at the first magnitude drawn within the limit:
            // redraws re-perturb it, so parents that ring (or fail more often) are not
            // replaced by easier ones.
            mag = first.mag + conditional_mag_spread(first, l.mag, draw) * stream.epanechnikov();
            if (!shape_chosen) {
                g.parent = near_in_magnitude(morphology, draw, mag, stream.uniform());
                shape_chosen = mag <= mag_limit;
            }
            p = &morphology.points[g.parent];
            beta = scaled_beta(*p, mag) + l.beta * stream.epanechnikov();
        } else {
            beta = p->beta + l.beta * stream.epanechnikov();
            mag = p->mag + l.mag * stream.epanechnikov();
        }
        // A shape that keeps failing (holes, too large a change) is perturbed less: halved
        // every 100 redraws, so it ends as new as positivity allows rather than a copy.
        drawn = perturb_shape(*p, l, std::ldexp(1.0, -(g.redraws / 100)), stream);
        if (beta > 0.0 && drawn.sum > 0.0 && mag <= mag_limit &&
            drawn.change <= draw.max_perturbation * draw.max_perturbation * drawn.norm) {
            // Past `hole_redraws` the shape is as close to its parent as halving makes it: its
            // holes are the parent's own, which the renderer clips (a copy of the magnitude
            // parent would be a clone).
            if (delta || p->n_max == 0 || g.redraws >= hole_redraws) break;
            if (rings_no_deeper(drawn.shape, *p, mag, beta, draw.hole_allowance)) break;
        }
    }
    g.mag = mag;
    g.beta = beta;
    g.flux = std::pow(10.0, -0.4 * (mag - zero_point));
    const double beta_pix = beta / pixel_scale;
    const double a00 = g.flux / (2.0 * std::sqrt(pi) * beta_pix * drawn.sum);
    g.rotation = stream.angle();
    g.reflected = stream.coin();
    const MorphologyPoint& shape_parent = morphology.points[g.parent];
    g.model = placed_model(drawn.shape, shape_parent.n_max, beta_pix, a00, g.rotation, g.reflected);
    g.perturbation = drawn.norm > 0.0 ? std::sqrt(drawn.change / drawn.norm) : 0.0;
    g.band_models = band_models(morphology, shape_parent, drawn, beta_pix, a00, g, stream);
    return g;
}

DrawnGalaxy draw_faint_galaxy(const Morphology& morphology, RandomStream& stream,
                              double pixel_scale, double zero_point, const DrawOptions& draw) {
    if (!draw.counts || draw.by_magnitude.empty())
        throw Error("faint galaxies need the fitted counts and the parents by magnitude");
    DrawOptions faint = draw;
    faint.neighbours = std::max(draw.neighbours, 1);
    faint.mix = morphology.lambda.is_delta() ? 1 : std::max(draw.mix, 1);
    return draw_mixture(morphology, {1.0}, stream, pixel_scale, zero_point, draw.counts->faint,
                        faint);
}

}  // namespace shapesim
