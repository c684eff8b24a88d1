#include "shapesim/decompose.hpp"

#include "shapesim/convolve.hpp"
#include "shapesim/error.hpp"
#include "shapesim/model.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/optimize.hpp"
#include "shapesim/polar.hpp"
#include "shapesim/render.hpp"
#include "shapesim/transform.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>

namespace shapesim {

void DecomposeOptions::validate() const {
    auto fail = [](const char* field, const char* why) { throw Error(why, "", 0, field); };
    if (n_max_min < 0) fail("n_max_min", "must be ≥ 0");
    if (n_max_cap < n_max_min) fail("n_max_cap", "must be ≥ n_max_min");
    if (n_max_cap > 100) fail("n_max_cap", "must be ≤ 100");
    if (!(chi2_target > 0.0)) fail("chi2_target", "must be > 0");
    if (!(chi2_sigmas >= 0.0)) fail("chi2_sigmas", "must be ≥ 0");
    if (!(beta_tolerance > 0.0 && beta_tolerance < 1.0))
        fail("beta_tolerance", "must be in (0, 1)");
    if (!(theta_min > 0.0)) fail("theta_min", "must be > 0");
    if (!(centre_tolerance > 0.0)) fail("centre_tolerance", "must be > 0");
    if (centre_iterations < 0) fail("centre_iterations", "must be ≥ 0");
    if (!(order_sigmas >= 0.0 && std::isfinite(order_sigmas))) fail("order_sigmas", "must be ≥ 0");
    if (!(bad_fit_chi2r > 0.0)) fail("bad_fit_chi2r", "must be > 0");
    if (!(max_hole >= 0.0)) fail("max_hole", "must be ≥ 0");
    if (!(max_unsupported >= 0.0 && max_unsupported <= 1.0))
        fail("max_unsupported", "must be in [0, 1]");
    if (!(noise_correlation >= 1.0 && std::isfinite(noise_correlation)))
        fail("noise_correlation", "must be ≥ 1");
}

double effective_dof(const ShapeletFit& fit, double noise_correlation) {
    const double p = double(real_count(fit.model.n_max));
    return std::max(1.0, double(fit.pixels_used) - p * noise_correlation * noise_correlation);
}

double effective_chi2r(const ShapeletFit& fit, double noise_correlation) {
    return fit.chi2 / effective_dof(fit, noise_correlation);
}

ShapeletFit fit_model(const ImageArray& image, const ImageArray& weight, const MaskArray* mask,
                      double x, double y, double beta_pix, int n_max,
                      const DecomposeOptions& options) {
    if (options.psf)
        return fit_convolved_shapelets(image, weight, mask, x, y, beta_pix, n_max, *options.psf,
                                       options.solver);
    return fit_shapelets(image, weight, mask, x, y, beta_pix, n_max, options.solver);
}

double noise_uptake(int from, int to, const DecomposeOptions& options) {
    const double extra = double(real_count(to) - real_count(from));
    const double f2 = options.noise_correlation * options.noise_correlation;
    return f2 * (extra + options.order_sigmas * std::sqrt(2.0 * extra));
}

bool within_target(const ShapeletFit& fit, double chi2r, const DecomposeOptions& options) {
    const double dof = effective_dof(fit, options.noise_correlation);
    return chi2r <= options.chi2_target + options.chi2_sigmas * std::sqrt(2.0 / dof);
}

namespace {

constexpr double infinite = std::numeric_limits<double>::infinity();

// One fit of every band at a common centre, β and n_max; χ² their sum. bands[0] is the
// reference band (one band: the plain fit).
struct JointFit {
    std::vector<ShapeletFit> bands;
    double chi2 = 0.0;
    std::vector<double> take_up;  // each band's noise take-up (JointProblem::account); empty: p·F²
    const ShapeletModel& model() const { return bands.front().model; }
};

// The bands of a joint fit with their per-band options (PSF, noise correlation).
class JointProblem {
public:
    JointProblem(const std::vector<BandStamp>& bands, const DecomposeOptions& options)
        : bands_(bands) {
        for (const BandStamp& b : bands) {
            DecomposeOptions o = options;
            if (b.psf) o.psf = *b.psf;
            if (b.correlation) o.correlation = *b.correlation;
            o.noise_correlation = b.noise_correlation;
            options_.push_back(std::move(o));
        }
        // The sharpest band's PSF variance (½ the trace of its second moments); none when a
        // band is fitted in the observed frame.
        for (const DecomposeOptions& o : options_) {
            double v = 0.0;
            if (o.psf) {
                const Moments m = moments(*o.psf);
                v = std::isfinite(m.q11 + m.q22) ? std::max(0.0, 0.5 * (m.q11 + m.q22)) : 0.0;
            }
            psf_variance_ = std::min(psf_variance_, v);
        }
        if (options_.empty()) psf_variance_ = 0.0;
    }
    // The smallest β of order n (pixels): the resolution limit θ_min·√(n+1) on the scale the
    // data see. An observed-frame model is seen at its own β; an intrinsic one through its PSF,
    // at √(β² + σ²) (second moments add under convolution; σ² the sharpest band's PSF
    // variance), so a galaxy smaller than the PSF keeps its small β rather than the pixel's.
    // A point source is a twentieth of the limit (the fit cannot tell it from one smaller).
    double smallest_beta(int n, const DecomposeOptions& o) const {
        const double limit2 = o.theta_min * o.theta_min * (n + 1.0);
        return std::sqrt(std::max(limit2 - psf_variance_, limit2 / 400.0));
    }
    std::size_t size() const { return bands_.size(); }
    const DecomposeOptions& options(std::size_t b) const { return options_[b]; }
    const BandStamp& band(std::size_t b) const { return bands_[b]; }

    JointFit fit(double x, double y, double beta, int n_max) const {
        JointFit out;
        out.bands.reserve(size());
        for (std::size_t b = 0; b < size(); ++b) {
            out.bands.push_back(fit_model(*bands_[b].image, *bands_[b].weight, bands_[b].mask, x,
                                          y, beta, n_max, options_[b]));
            out.chi2 += out.bands.back().chi2;
        }
        return out;
    }
    // The elliptical lowest order's shape in every band, each its own amplitude.
    JointFit fit_shape(double x, double y, const ShapeletModel& shape) const {
        JointFit out;
        for (std::size_t b = 0; b < size(); ++b) {
            const auto& psf = options_[b].psf;
            out.bands.push_back(fit_shape_amplitude(*bands_[b].image, *bands_[b].weight,
                                                    bands_[b].mask, x, y, shape,
                                                    psf ? &*psf : nullptr));
            out.chi2 += out.bands.back().chi2;
        }
        return out;
    }
    // Band b as a multiple of `shape` (its centre the shape's).
    ShapeletFit fit_band_shape(std::size_t b, const ShapeletModel& shape) const {
        const auto& psf = options_[b].psf;
        return fit_shape_amplitude(*bands_[b].image, *bands_[b].weight, bands_[b].mask, shape.x,
                                   shape.y, shape, psf ? &*psf : nullptr);
    }
    // Whether any band's noise correlation is known: the exact take-up replaces p·F².
    bool exact() const {
        for (const DecomposeOptions& o : options_)
            if (o.correlation) return true;
        return false;
    }
    // Each band's noise take-up T_b (lsq.hpp noise_take_up; p·F_b² where no correlation).
    void account(JointFit& f) const {
        const ShapeletModel& m = f.model();
        f.take_up.clear();
        for (std::size_t b = 0; b < size(); ++b) {
            const DecomposeOptions& o = options_[b];
            const double F = o.noise_correlation;
            f.take_up.push_back(
                o.correlation ? noise_take_up(*bands_[b].image, *bands_[b].weight, bands_[b].mask,
                                              m.x, m.y, m.beta_pix, m.n_max, *o.correlation,
                                              o.psf ? &*o.psf : nullptr)
                              : double(real_count(m.n_max)) * F * F);
        }
    }
    // Band b's pixels − T_b (T_b = p·F_b² unless accounted), at least 1.
    double band_dof(const JointFit& f, std::size_t b) const {
        if (f.take_up.empty()) return effective_dof(f.bands[b], options_[b].noise_correlation);
        return std::max(1.0, double(f.bands[b].pixels_used) - f.take_up[b]);
    }
    // Σ_b (pixels_b − T_b), at least 1 (effective_dof() for one band without a correlation).
    double dof(const JointFit& f) const {
        double sum = 0.0;
        if (!f.take_up.empty()) {
            for (std::size_t b = 0; b < size(); ++b)
                sum += double(f.bands[b].pixels_used) - f.take_up[b];
            return std::max(1.0, sum);
        }
        const double p = double(real_count(f.model().n_max));
        for (std::size_t b = 0; b < size(); ++b) {
            const double F = options_[b].noise_correlation;
            sum += double(f.bands[b].pixels_used) - p * F * F;
        }
        return std::max(1.0, sum);
    }
    // The elliptical lowest order's: three parameters besides β (amplitude and shear).
    double elliptical_dof(const JointFit& f) const {
        double sum = 0.0;
        for (std::size_t b = 0; b < size(); ++b) {
            const double F = options_[b].noise_correlation;
            sum += double(f.bands[b].pixels_used) - 3.0 * (F * F);
        }
        return std::max(1.0, sum);
    }
    double chi2r(const JointFit& f) const { return f.chi2 / dof(f); }
    // within_target() over the joint degrees of freedom.
    bool within_target(double chi2r, double dof, const DecomposeOptions& o) const {
        return chi2r <= o.chi2_target + o.chi2_sigmas * std::sqrt(2.0 / dof);
    }
    // The χ² the noise takes up in every band from order `from` to `to`: noise_uptake() for
    // one band; for several, Σ F_b²·Δp + order_sigmas·√(2Δp Σ F_b⁴).
    double uptake(int from, int to, const DecomposeOptions& o) const {
        if (size() == 1) return noise_uptake(from, to, options_[0]);
        const double extra = double(real_count(to) - real_count(from));
        double f2 = 0.0, f4 = 0.0;
        for (const DecomposeOptions& b : options_) {
            const double F2 = b.noise_correlation * b.noise_correlation;
            f2 += F2;
            f4 += F2 * F2;
        }
        return f2 * extra + o.order_sigmas * std::sqrt(2.0 * extra * f4);
    }
    // The same from the accounted fits of two orders: ΔT = Σ_b ΔT_b, each band's extra
    // coefficients taking up λ_b = ΔT_b/Δp apiece, so the scatter is √(2Δp Σ λ_b²) (the rule
    // above when every T_b = p·F_b²).
    double uptake(const JointFit& from, const JointFit& to, const DecomposeOptions& o) const {
        const double extra = double(real_count(to.model().n_max) - real_count(from.model().n_max));
        double sum = 0.0, squares = 0.0;
        for (std::size_t b = 0; b < size(); ++b) {
            const double added = std::max(0.0, to.take_up[b] - from.take_up[b]);
            sum += added;
            squares += extra > 0.0 ? added * added / extra : 0.0;
        }
        return sum + o.order_sigmas * std::sqrt(2.0 * squares);
    }
    // The bands' mean F²: the χ² a fitted parameter's noise takes up, per parameter.
    double mean_noise_factor2() const {
        double f2 = 0.0;
        for (const DecomposeOptions& b : options_) f2 += b.noise_correlation * b.noise_correlation;
        return f2 / double(size());
    }
    // The χ² two more parameters (the shear) would take up from noise in every band:
    // F²·(2 + order_sigmas·2) for one band.
    double shear_uptake(const DecomposeOptions& o) const {
        double f2 = 0.0, f4 = 0.0;
        for (const DecomposeOptions& b : options_) {
            const double F2 = b.noise_correlation * b.noise_correlation;
            f2 += F2;
            f4 += F2 * F2;
        }
        if (size() == 1) return f2 * (2.0 + o.order_sigmas * 2.0);
        return 2.0 * f2 + o.order_sigmas * 2.0 * std::sqrt(f4);
    }
    // The model whose centroid recentring follows: the reference band's alone, or the bands'
    // coefficients summed, each weighted by 1/σ of its stamp's noise (a χ²-like stack, as a
    // detection image is).
    ShapeletModel centroid_model(const JointFit& f) const {
        if (size() == 1) return f.model();
        ShapeletModel stack = f.model();
        for (Complex& c : stack.coeffs) c = 0.0;
        for (std::size_t b = 0; b < size(); ++b)
            for (std::size_t k = 0; k < stack.coeffs.size(); ++k)
                stack.coeffs[k] += bands_[b].signal_weight * f.bands[b].model.coeffs[k];
        return stack;
    }

private:
    const std::vector<BandStamp>& bands_;
    std::vector<DecomposeOptions> options_;
    double psf_variance_ = std::numeric_limits<double>::infinity();
};

// One order's search state: joint fits at (x, y, β), scored by the effective χ²_r.
class OrderSearch {
public:
    OrderSearch(const JointProblem& problem, int n_max, const DecomposeOptions& options,
                long& fits)
        : problem_(problem), n_max_(n_max), options_(options), fits_(fits) {}

    // χ²_r at (x, y, β); +∞ when the fit is impossible (too few pixels, rank-deficient).
    double score(double x, double y, double beta) {
        fits_ += long(problem_.size());
        try {
            JointFit fit = problem_.fit(x, y, beta, n_max_);
            const double chi2r = problem_.chi2r(fit);
            if (!std::isfinite(chi2r)) return infinite;
            if (chi2r < best_chi2r_) {
                best_chi2r_ = chi2r;
                best_ = std::move(fit);
            }
            return chi2r;
        } catch (const Error&) {
            return infinite;
        }
    }

    // Golden-section search of ln β over [lo, hi] at a fixed centre, after a coarse scan of
    // five points that picks the bracket (χ²_r(β) can have more than one dip).
    // With `scan` false the search is local: golden section over [lo, hi] directly.
    double best_beta(double x, double y, double lo, double hi, bool scan = true) {
        const double a = std::log(lo), b = std::log(hi);
        if (b - a < options_.beta_tolerance) {  // the constraints leave one β
            const double only = std::exp(0.5 * (a + b));
            score(x, y, only);
            return only;
        }
        double left = a, right = b;
        if (scan) {
            constexpr int coarse = 5;
            double u[coarse], f[coarse];
            int best = 0;
            for (int k = 0; k < coarse; ++k) {
                u[k] = a + (b - a) * k / (coarse - 1);
                f[k] = score(x, y, std::exp(u[k]));
                if (f[k] < f[best]) best = k;
            }
            left = u[std::max(best - 1, 0)];
            right = u[std::min(best + 1, coarse - 1)];
        }
        const auto bracket = golden_section(
            [&](double u) { return score(x, y, std::exp(u)); }, left, right,
            options_.beta_tolerance, std::less<double>(), [](double) {});
        return bracket.fc < bracket.fd ? std::exp(bracket.c) : std::exp(bracket.d);
    }

    const std::optional<JointFit>& best() const { return best_; }
    double best_chi2r() const { return best_chi2r_; }
    void forget() {
        best_.reset();
        best_chi2r_ = infinite;
    }

private:
    const JointProblem& problem_;
    int n_max_;
    const DecomposeOptions& options_;
    long& fits_;
    std::optional<JointFit> best_;
    double best_chi2r_ = infinite;
};

}  // namespace

ShapeletModel elliptical_gaussian(double beta_pix, double g1, double g2) {
    ShapeletModel round(0.0, 0.0, beta_pix, 0);
    round.coeffs[0] = 1.0;
    ProjectionOptions order;
    order.n_out = elliptical_order;
    return shear(round, g1, g2, order).model;
}

namespace {

// The elliptical lowest order (see decompose.hpp): the sheared Gaussian of least χ² at the
// round fit's centre, (g1, g2, ln β) by Nelder–Mead (optimize.hpp) from the round fit's β;
// in several bands one shape, each band its own amplitude.
// The largest reduced shear the elliptical lowest order is fitted at (its axis ratio 19).
constexpr double max_elliptical_shear = 0.9;

struct EllipticalFit {
    JointFit fit;
    double g1 = 0.0, g2 = 0.0;
};
std::optional<EllipticalFit> fit_elliptical(const JointProblem& problem, const JointFit& round,
                                            double reach, const DecomposeOptions& options,
                                            long& fits) {
    const double theta_min = problem.smallest_beta(0, options);
    const double x = round.model().x, y = round.model().y;
    std::optional<EllipticalFit> best;
    const auto chi2 = [&](const std::array<double, 3>& v) {
        const double g = std::hypot(v[0], v[1]), beta = std::exp(v[2]);
        // The minor axis resolved as n_max 0's β must be, the major axis inside the stamp.
        if (!(g < max_elliptical_shear) || beta * std::sqrt((1.0 - g) / (1.0 + g)) < theta_min ||
            beta * std::sqrt((1.0 + g) / (1.0 - g)) > reach)
            return infinite;
        fits += long(problem.size());
        try {
            JointFit fit = problem.fit_shape(x, y, elliptical_gaussian(beta, v[0], v[1]));
            const double value = fit.chi2;
            if (!std::isfinite(value)) return infinite;
            if (!best || value < best->fit.chi2) best = EllipticalFit{std::move(fit), v[0], v[1]};
            return value;
        } catch (const Error&) {
            return infinite;
        }
    };
    NelderMeadOptions search;
    search.step = 0.15;   // in g and in ln β
    search.xatol = 1e-3;
    search.fatol = 1e-3;  // in χ²
    search.max_calls = 200;
    nelder_mead<3>(chi2, {0.0, 0.0, std::log(round.model().beta_pix)}, search);
    return best;
}

// The share of a model's light that no datum constrains: outside the stamp, on a neighbour's
// (masked) pixels or on pixels of zero weight. The fit is free to put light there (a scale
// grown to the stamp's size to take up a neighbour's wings, extrapolated past the edge).
double unsupported_light(const CartesianModel& model, const BandStamp& band) {
    const ImageArray& weight = *band.weight;
    const Eigen::Index nx = weight.cols(), ny = weight.rows();
    // Out to where a Gaussian-weighted series is ~e^{-4.5} of its centre and beyond.
    const double extent = model.beta_pix * (std::sqrt(2.0 * model.n_max + 1.0) + 3.0);
    const int margin = int(std::ceil(std::min(extent, 1024.0)));
    CartesianModel shifted = model;
    shifted.x += margin;
    shifted.y += margin;
    const ImageArray all = render_stamp(shifted, int(nx) + 2 * margin, int(ny) + 2 * margin);
    double supported = 0.0;
    for (Eigen::Index j = 0; j < ny; ++j)
        for (Eigen::Index i = 0; i < nx; ++i)
            if (weight(j, i) > 0.0 && !(band.mask && (*band.mask)(j, i) != 0))
                supported += all(j + margin, i + margin);
    const double total = all.sum();
    // No positive light at all is the noise flag's case, not this one's.
    return total > 0.0 ? 1.0 - supported / total : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace

Decomposition decompose(const ImageArray& image, const ImageArray& weight, const MaskArray* mask,
                        double x, double y, double beta_start, const DecomposeOptions& options) {
    BandStamp band;
    band.image = &image;
    band.weight = &weight;
    band.mask = mask;
    band.noise_correlation = options.noise_correlation;
    Decomposition out = decompose_bands({band}, x, y, beta_start, options);
    out.bands.clear();  // a one-band fit: the fields above say it all
    return out;
}

namespace {

// What decompose_bands() refuses: no band, a band without image or weight, stamps of
// different sizes, a start centre outside the stamp, a start β ≤ 0.
void check_bands(const std::vector<BandStamp>& bands, double x, double y, double beta_start) {
    require(!bands.empty(), "no band to fit");
    for (const BandStamp& b : bands) require(b.image && b.weight, "a band has no image or weight");
    const ImageArray& image = *bands.front().image;
    const double nx = double(image.cols()), ny = double(image.rows());
    require(nx > 0 && ny > 0, "stamp is empty");
    for (const BandStamp& b : bands) {
        const auto same = [&](const auto& plane) {
            return plane.rows() == image.rows() && plane.cols() == image.cols();
        };
        require(same(*b.image) && same(*b.weight) && (!b.mask || same(*b.mask)),
                "the bands' stamps (image, weight, mask) differ in size");
    }
    require(std::isfinite(x) && std::isfinite(y) && x >= 0.5 && x <= nx + 0.5 && y >= 0.5 &&
                y <= ny + 0.5,
            "start centre lies outside the stamp");
    require(beta_start > 0.0 && std::isfinite(beta_start), "start β must be > 0");
}

// A fit with the χ²_r it was chosen by.
struct ScoredFit {
    JointFit fit;
    double chi2r = infinite;
};

// A centre in stamp FITS coordinates.
struct Centre {
    double x = 0.0, y = 0.0;
};

// Recentre order n's fit on the model's own centroid; after a large move, search β again. The
// iteration can wander at a galaxy's own top order (the centroid of a fit that is just short
// of the data moves off it): the best (χ²_r) position seen is returned, `seen` at first.
std::optional<ScoredFit> recentre(const JointProblem& problem, OrderSearch& search,
                                  std::optional<ScoredFit> seen, Centre at, double beta,
                                  Centre start, double lo, double hi,
                                  const DecomposeOptions& options) {
    for (int iteration = 0; iteration < options.centre_iterations && search.best(); ++iteration) {
        const Moments m = moments(problem.centroid_model(*search.best()));
        if (!std::isfinite(m.x) || !std::isfinite(m.y)) break;
        // Stay within a few pixels of the detection: a centroid dragged further is a fit
        // to a neighbour's or the noise's light.
        const double new_x = std::clamp(m.x, start.x - 3.0, start.x + 3.0);
        const double new_y = std::clamp(m.y, start.y - 3.0, start.y + 3.0);
        const double shift = std::hypot(new_x - at.x, new_y - at.y);
        if (shift < options.centre_tolerance) break;
        at = {new_x, new_y};
        search.forget();
        // A large move may change which dip in χ²_r(β) is deepest: scan again; a small
        // one only moves the minimum: search ±10% about the current β.
        if (shift > 0.25) beta = search.best_beta(at.x, at.y, lo, hi);
        else
            beta = search.best_beta(at.x, at.y, std::max(lo, beta / 1.1),
                                    std::min(hi, beta * 1.1), false);
        if (!search.best() || !(search.best_chi2r() < seen->chi2r)) break;
        seen = ScoredFit{*search.best(), search.best_chi2r()};
    }
    return seen;
}

// Order n's best fit (least χ²_r) from centre `at`: β scanned within [lo, hi], the centre moved to
// the model's centroid (recentre()), and the detection's centre `start` tried as a second start
// (the previous order's centre may already have wandered). Empty when no fit of this order is
// possible.
std::optional<ScoredFit> best_of_order(const JointProblem& problem, OrderSearch& search,
                                       Centre at, Centre start, double lo, double hi,
                                       const DecomposeOptions& options) {
    const double beta = search.best_beta(at.x, at.y, lo, hi);
    std::optional<ScoredFit> seen;
    if (search.best()) seen = ScoredFit{*search.best(), search.best_chi2r()};
    seen = recentre(problem, search, std::move(seen), at, beta, start, lo, hi, options);
    if (seen && std::hypot(seen->fit.model().x - start.x, seen->fit.model().y - start.y) >
                    options.centre_tolerance) {
        search.forget();
        const double b = seen->fit.model().beta_pix;
        search.best_beta(start.x, start.y, std::max(lo, b / 1.1), std::min(hi, b * 1.1), false);
        if (search.best() && search.best_chi2r() < seen->chi2r)
            seen = ScoredFit{*search.best(), search.best_chi2r()};
    }
    return seen;
}

// The orders n_max_min, n_max_min + 1, … each fitted from the previous order's centre
// (best_of_order(); each order scans β afresh); an order becomes the candidate when it takes up
// significantly more χ² than the noise would over the candidate's, and the search stops two orders
// beyond the candidate, at the cap or when the stamp is too small. Each order's trial, the fits
// made and why the search stopped go to `out`; the candidate is returned. `reach` is the largest
// scale inside the stamp.
ScoredFit search_orders(const JointProblem& problem, Centre start, double reach,
                        const DecomposeOptions& options, Decomposition& out) {
    std::optional<ScoredFit> kept;
    Centre at = start;
    for (int n = options.n_max_min; n <= options.n_max_cap; ++n) {
        const double root = std::sqrt(n + 1.0);
        const double lo = problem.smallest_beta(n, options), hi = reach / root;
        if (lo > hi) {
            out.stop = "stamp_small";
            break;
        }
        OrderSearch search(problem, n, options, out.fits);
        std::optional<ScoredFit> order =
            best_of_order(problem, search, at, start, lo, hi, options);
        if (!order) {
            if (!kept) throw Error("no usable fit: too few usable pixels in the stamp");
            out.stop = "stamp_small";
            break;
        }
        // With a measured correlation the order's fit is scored by its exact take-up (the β
        // search's p·F² is a constant per order: the same minimum).
        JointFit best = std::move(order->fit);
        if (problem.exact()) problem.account(best);
        const double chi2r = problem.exact() ? best.chi2 / problem.dof(best) : order->chi2r;
        out.trials.push_back({n, best.model().beta_pix, chi2r});
        at = {best.model().x, best.model().y};
        const int kept_n = kept ? kept->fit.model().n_max : 0;
        const double uptake = !kept            ? 0.0
                              : problem.exact() ? problem.uptake(kept->fit, best, options)
                                                : problem.uptake(kept_n, n, options);
        if (!kept || kept->fit.chi2 - best.chi2 > uptake) kept = ScoredFit{best, chi2r};
        if (n >= kept->fit.model().n_max + 2) {  // two orders beyond it brought nothing
            out.stop = problem.within_target(kept->chi2r, problem.dof(kept->fit), options)
                           ? "chi2_target"
                           : "flattened";
            break;
        }
        if (n == options.n_max_cap) out.stop = "n_max_cap";
    }
    if (!kept) throw Error("no usable fit: the stamp is too small for the lowest order");
    return std::move(*kept);
}

// The elliptical lowest order in place of a round n_max 0 candidate. The best-fitting shear g
// is the galaxy's plus the noise's, E|g|² = |g_true|² + tr C (C the shear's covariance, 2F²
// times the inverse of χ²'s curvature in (g1, g2) at the best fit, β held): kept as it is, a
// faint galaxy's model is more elongated than the galaxy, and kept round (below the noise) it
// is rounder, so a faint population of either is not the sky's. The model takes the shear with
// the noise's share taken out in quadrature, ĝ = g·√(1 − tr C/|g|²) (E|ĝ|² = |g_true|²),
// its amplitude fitted again; round where |g|² ≤ tr C. Where the curvature is not positive the
// best fit is kept when its two more parameters take up more χ² than the noise would.
void try_elliptical(const JointProblem& problem, ScoredFit& kept, double reach,
                    const DecomposeOptions& options, Decomposition& out) {
    const std::optional<EllipticalFit> e =
        fit_elliptical(problem, kept.fit, reach, options, out.fits);
    if (!e) return;
    const ShapeletModel& best = e->fit.model();
    const auto chi2_at = [&](double g1, double g2) {
        out.fits += long(problem.size());
        return problem.fit_shape(best.x, best.y, elliptical_gaussian(best.beta_pix, g1, g2)).chi2;
    };
    double trace_c = std::numeric_limits<double>::quiet_NaN();
    constexpr double h = 0.02;
    if (std::hypot(e->g1, e->g2) + 2.0 * h < max_elliptical_shear) {
        try {
            const double f0 = e->fit.chi2;
            const double fx1 = chi2_at(e->g1 + h, e->g2), fx0 = chi2_at(e->g1 - h, e->g2);
            const double fy1 = chi2_at(e->g1, e->g2 + h), fy0 = chi2_at(e->g1, e->g2 - h);
            const double fxy = chi2_at(e->g1 + h, e->g2 + h);
            const double h11 = (fx1 - 2.0 * f0 + fx0) / (h * h);
            const double h22 = (fy1 - 2.0 * f0 + fy0) / (h * h);
            const double h12 = (fxy - fx1 - fy1 + f0) / (h * h);
            const double det = h11 * h22 - h12 * h12;
            if (h11 > 0.0 && h22 > 0.0 && det > 0.0)
                trace_c = 2.0 * problem.mean_noise_factor2() * (h11 + h22) / det;
        } catch (const Error&) {
            // a shear at the edge of the stamp's support: no curvature
        }
    }
    const double g2 = e->g1 * e->g1 + e->g2 * e->g2;
    if (!std::isfinite(trace_c)) {
        if (kept.fit.chi2 - e->fit.chi2 <= problem.shear_uptake(options)) return;
        kept.fit = e->fit;
        out.g1 = e->g1;
        out.g2 = e->g2;
    } else {
        if (!(g2 > trace_c)) return;
        const double shrink = std::sqrt(1.0 - trace_c / g2);
        out.g1 = e->g1 * shrink;
        out.g2 = e->g2 * shrink;
        out.fits += long(problem.size());
        kept.fit = problem.fit_shape(best.x, best.y,
                                     elliptical_gaussian(best.beta_pix, out.g1, out.g2));
    }
    kept.chi2r = kept.fit.chi2 / problem.elliptical_dof(kept.fit);
    out.elliptical = true;
}

// The kept fit's verdicts: χ²_r, converged, why the search stopped, bad_fit, holes and
// unsupported light.
void judge(const JointProblem& problem, const ScoredFit& kept, const DecomposeOptions& options,
           Decomposition& out) {
    out.chi2r = kept.chi2r;
    out.converged = problem.within_target(out.chi2r, problem.dof(kept.fit), options);
    // The cap only stopped the search if the orders it cut off were still wanted.
    if (out.stop == "n_max_cap" && kept.fit.model().n_max < options.n_max_cap)
        out.stop = out.converged ? "chi2_target" : "flattened";
    out.bad_fit = out.chi2r > options.bad_fit_chi2r;
    // In the frame the data see: an intrinsic model through its PSF (ringing finer than the
    // PSF is not measured, and a render through a broader or matched PSF does not show it).
    // Several bands: the S/N-weighted stack's, the model the joint fit constrains best (a
    // faint band's own coefficients ring with its noise at the order the bright bands chose).
    const auto& psf = problem.options(0).psf;
    const ShapeletModel judged = problem.centroid_model(kept.fit);
    const CartesianModel seen = psf ? convolve(to_cartesian(judged), *psf) : to_cartesian(judged);
    const PixelHoles holes = pixel_holes(seen);
    out.hole = holes.depth;
    out.negative_light = holes.negative_light;
    out.holes = !(out.hole <= options.max_hole && out.negative_light <= options.max_hole);
    out.unsupported_light = unsupported_light(seen, problem.band(0));
    out.unsupported = out.unsupported_light > options.max_unsupported;
}

// Each band's flux error with β's share: the fixed-β error `fixed` plus β's share from the
// joint profile χ² at ln β ± h (the fixed-β error alone where that cannot be had).
std::vector<double> beta_flux_errors(const JointProblem& problem, const JointFit& kept,
                                     const std::vector<double>& fixed, Decomposition& out) {
    std::vector<double> errors = fixed;
    constexpr double h = 0.05;
    try {
        const ShapeletModel& m = kept.model();
        // At β e^{±h}: the same family (an elliptical model keeps its shear).
        const auto at = [&](double beta_pix) {
            if (!out.elliptical) return problem.fit(m.x, m.y, beta_pix, m.n_max);
            return problem.fit_shape(m.x, m.y, elliptical_gaussian(beta_pix, out.g1, out.g2));
        };
        const JointFit lo = at(m.beta_pix * std::exp(-h));
        const JointFit hi = at(m.beta_pix * std::exp(h));
        out.fits += 2 * long(problem.size());
        const double curvature = (lo.chi2 + hi.chi2 - 2.0 * kept.chi2) / (h * h);
        for (std::size_t b = 0; b < problem.size(); ++b) {
            const double slope = (flux(hi.bands[b].model) - flux(lo.bands[b].model)) / (2.0 * h);
            if (curvature > 0.0 && std::isfinite(slope)) {
                const double F = problem.options(b).noise_correlation, f2 = F * F;
                errors[b] = std::sqrt(fixed[b] * fixed[b] + slope * slope * 2.0 * f2 / curvature);
            }
        }
    } catch (const Error&) {
        // β at a constraint edge with too few pixels beyond it: keep the fixed-β error.
    }
    return errors;
}

// Truncation's share of each band's flux error, added to `errors`: the flux the orders above
// n_max would still move, estimated from the fit four orders up at the same centre and β (two
// more flux-carrying even orders), less the noise variance those extra coefficients add to
// the difference (nested least-squares fits: Var(F' − F) = σ'² − σ²). Zero when there are
// too few pixels for the higher order.
std::vector<double> truncation_errors(const JointProblem& problem, const JointFit& kept,
                                      const std::vector<double>& fixed,
                                      std::vector<double>& errors, long& fits) {
    std::vector<double> truncation(problem.size(), 0.0);
    try {
        const ShapeletModel& m = kept.model();
        const JointFit up = problem.fit(m.x, m.y, m.beta_pix, m.n_max + truncation_orders);
        fits += long(problem.size());
        for (std::size_t b = 0; b < problem.size(); ++b) {
            const double change = flux(up.bands[b].model) - flux(kept.bands[b].model);
            const double up_error = flux_error(up.bands[b]);
            truncation[b] = std::sqrt(
                std::max(0.0, change * change - (up_error * up_error - fixed[b] * fixed[b])));
            errors[b] = std::hypot(errors[b], truncation[b]);
        }
    } catch (const Error&) {
        // Too few pixels for the higher order: no truncation estimate.
    }
    return truncation;
}

// Several bands: a band whose own structure the noise could hold is the stack's shape times
// an amplitude (its colour), not a copy of its noise (see decompose_bands()). Such bands'
// fits in `kept` are replaced; which ones is returned.
std::vector<bool> template_noisy_bands(const JointProblem& problem, JointFit& kept,
                                       const DecomposeOptions& options, Decomposition& out) {
    std::vector<bool> templated(problem.size(), false);
    if (problem.size() == 1 || out.elliptical) return templated;
    const ShapeletModel stack = problem.centroid_model(kept);
    const double extra = double(real_count(stack.n_max) - 1);
    for (std::size_t b = 0; b < problem.size() && extra > 0.0; ++b) {
        try {
            ShapeletFit shaped = problem.fit_band_shape(b, stack);
            ++out.fits;
            const double F = problem.options(b).noise_correlation;
            const double uptake = F * F * (extra + options.order_sigmas * std::sqrt(2.0 * extra));
            if (shaped.chi2 - kept.bands[b].chi2 <= uptake) {
                kept.bands[b] = std::move(shaped);
                templated[b] = true;
            }
        } catch (const Error&) {
            // The stack's shape leaves the band no light: keep its own fit.
        }
    }
    return templated;
}

}  // namespace

Decomposition decompose_bands(const std::vector<BandStamp>& bands, double x, double y,
                              double beta_start, const DecomposeOptions& options) {
    options.validate();
    check_bands(bands, x, y, beta_start);
    const JointProblem problem(bands, options);
    Decomposition out;
    // Largest scale inside the stamp, measured from the start centre (the centre moves by a
    // fraction of a pixel, the bound need not follow it).
    const double nx = double(bands.front().image->cols()), ny = double(bands.front().image->rows());
    const double reach = std::min(std::min(x - 0.5, nx + 0.5 - x), std::min(y - 0.5, ny + 0.5 - y));
    ScoredFit kept = search_orders(problem, {x, y}, reach, options, out);
    if (options.elliptical && kept.fit.model().n_max == 0 &&
        options.n_max_cap >= elliptical_order)
        try_elliptical(problem, kept, reach, options, out);
    judge(problem, kept, options, out);

    std::vector<double> fixed(problem.size());
    for (std::size_t b = 0; b < problem.size(); ++b) fixed[b] = flux_error(kept.fit.bands[b]);
    std::vector<double> errors = beta_flux_errors(problem, kept.fit, fixed, out);
    const std::vector<double> truncation =
        truncation_errors(problem, kept.fit, fixed, errors, out.fits);
    const std::vector<bool> templated = template_noisy_bands(problem, kept.fit, options, out);
    out.flux_error = errors.front();
    out.truncation_error = truncation.front();
    for (std::size_t b = 0; b < problem.size(); ++b) {
        BandFit f;
        f.fit = kept.fit.bands[b];
        f.flux_error = errors[b];  // the band's own fit's: the larger
        f.truncation_error = truncation[b];
        f.chi2r = kept.fit.bands[b].chi2 / problem.band_dof(kept.fit, b);
        f.templated = templated[b];
        out.bands.push_back(std::move(f));
    }
    out.fit = std::move(kept.fit.bands.front());
    return out;
}

double flux_error(const ShapeletFit& fit) {
    // Flux is linear in the real parameters: F = gᵀp with g_k = flux of the k-th unit vector.
    const int p = real_count(fit.model.n_max);
    if (fit.covariance.rows() != p) return std::numeric_limits<double>::quiet_NaN();
    Eigen::VectorXd g(p);
    ShapeletModel unit = fit.model;
    for (int k = 0; k < p; ++k) {
        Eigen::VectorXd e = Eigen::VectorXd::Zero(p);
        e(k) = 1.0;
        set_real_parameters(unit, e);
        g(k) = flux(unit);
    }
    return std::sqrt(std::max(0.0, g.dot(fit.covariance * g)));
}

}  // namespace shapesim
