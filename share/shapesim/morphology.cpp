#include "shapesim/morphology.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/convolve.hpp"
#include "shapesim/deconvolution.hpp"
#include "shapesim/error.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/positivity.hpp"
#include "shapesim/render.hpp"
#include "shapesim/shear_estimate.hpp"
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

namespace {

bool nonzero(Complex c, double scale) { return std::abs(c) > 1e-12 * scale; }

}  // namespace

ShapeletModel align(const ShapeletModel& model, Alignment* how) {
    Alignment a;
    const double scale = std::max(std::abs(model.coeffs[0]), 1e-300);
    const std::vector<PolarIndex> index = polar_indices(model.n_max);
    ShapeletModel out = model;
    // The rotation: the ellipticity χ of the closed-form quadrupole moments (every m = 2
    // coefficient contributes, a_{2,2} most), else a_{2,2}, else the first non-zero m ≥ 1
    // coefficient, made real and positive. `m` is the symmetry order of what was aligned.
    int m = 0;
    const Moments moment = moments(model);
    if (std::isfinite(std::abs(moment.chi)) && std::abs(moment.chi) > 1e-12) {
        // rotate(ρ) turns χ by e^{2iρ} (the object turns by ρ): undo its phase.
        m = 2;
        a.rotation = -std::arg(moment.chi) / 2.0;
    } else {
        std::optional<std::size_t> lead;
        if (model.n_max >= 2 && nonzero(model.at(2, 2), scale)) lead = polar_index(2, 2);
        for (std::size_t k = 0; !lead && k < index.size(); ++k)
            if (index[k].m >= 1 && nonzero(model.coeffs[k], scale)) lead = k;
        if (lead) {
            m = index[*lead].m;
            a.rotation = std::arg(model.coeffs[*lead]) / m;  // rotate() multiplies by e^{−imρ}
        }
    }
    if (m > 0) {
        out = rotate(model, a.rotation);
        // Rotations by 2π/m keep the lead; for even m one of them is π, which flips the
        // odd-m coefficients: make the first one with Re ≠ 0 have Re > 0.
        if (m % 2 == 0)
            for (std::size_t k = 0; k < index.size(); ++k)
                if (index[k].m % 2 == 1 && std::abs(out.coeffs[k].real()) > 1e-12 * scale) {
                    if (out.coeffs[k].real() < 0.0) {
                        a.rotation += pi;
                        out = rotate(model, a.rotation);
                    }
                    break;
                }
        // The reflection (a → conj a keeps χ and a real lead real): Im a_{4,2} ≥ 0, else
        // the first later coefficient with Im ≠ 0.
        // Even m first: the π choice above may still be open for the odd ones.
        const std::size_t from = model.n_max >= 4 ? std::size_t(polar_index(4, 2)) : 0;
        for (int parity : {0, 1}) {
            std::size_t k = from;
            while (k < index.size() && !(index[k].m >= 1 && index[k].m % 2 == parity &&
                                         std::abs(out.coeffs[k].imag()) > 1e-12 * scale))
                ++k;
            if (k == index.size()) continue;
            if (out.coeffs[k].imag() < 0.0) {
                a.reflected = true;
                out = reflect_x(out);
            }
            break;
        }
    }
    if (how) *how = a;
    return out;
}

ShapeletModel unalign(const ShapeletModel& aligned, const Alignment& how) {
    return rotate(how.reflected ? reflect_x(aligned) : aligned, -how.rotation);
}

bool SmoothingLengths::is_delta() const {
    if (phase_deg != 0.0 || beta != 0.0 || mag != 0.0) return false;
    const auto zero = [](double l) { return l == 0.0; };
    return std::all_of(coefficient.begin(), coefficient.end(), zero) && colour == 0.0;
}

void SmoothOptions::validate() const {
    auto check = [](double v, const char* field) {
        if (!(v >= 0.0 && std::isfinite(v))) throw Error("must be finite and ≥ 0", "", 0, field);
    };
    check(k, "k");
    check(phase_deg, "lambda_phase");
    if (beta) check(*beta, "lambda_beta");
    if (mag) check(*mag, "lambda_mag");
    if (modulus) check(*modulus, "lambda_modulus");
    check(colour, "lambda_colour");
}

double mean_nearest_neighbour_separation(std::vector<double> values) {
    if (values.size() < 2) return 0.0;
    std::sort(values.begin(), values.end());
    double sum = 0.0;
    for (std::size_t i = 0; i < values.size(); ++i) {
        double d = std::numeric_limits<double>::infinity();
        if (i > 0) d = values[i] - values[i - 1];
        if (i + 1 < values.size()) d = std::min(d, values[i + 1] - values[i]);
        sum += d;
    }
    return sum / double(values.size());
}

namespace {

// A record's number field, or none when absent or not a number (records pass fields on
// unchecked; a field the model can do without is not an error).
std::optional<double> number_or_none(const Json& extra, const char* field) {
    const auto it = extra.find(field);
    return it != extra.end() && it->is_number() ? std::optional(it->get<double>()) : std::nullopt;
}

}  // namespace

double even_sum(const std::vector<Complex>& shape) {
    double sum = 0.0;
    int k = 0;
    for (int n = 0; k < int(shape.size()); ++n)
        for (int m = n % 2; m <= n && k < int(shape.size()); m += 2, ++k)
            if (m == 0 && n % 2 == 0) sum += shape[std::size_t(k)].real();
    return sum;
}

double flux_ratio(const MorphologyPoint& p, std::size_t band) {
    const double sum = even_sum(p.shape);
    return sum != 0.0 ? even_sum(p.band_shapes.at(band)) / sum
                      : std::numeric_limits<double>::quiet_NaN();
}

namespace {

// A record's bands as point `p`'s band shapes (aligned as its reference shape, over the
// reference a_{0,0}); the first record with bands sets the morphology's band list, and every
// record must then carry the same bands in the same order.
void add_band_shapes(Morphology& out, const ShapeletRecord& r, MorphologyPoint& p, double a00) {
    const bool first = out.points.empty();
    if (first)
        for (const BandCoefficients& b : r.bands) {
            out.bands.push_back(b.band);
            out.band_zero_points.push_back(number_or_none(b.extra, "zero_point"));
        }
    bool same = r.bands.size() == out.bands.size();
    for (std::size_t b = 0; same && b < r.bands.size(); ++b) same = r.bands[b].band == out.bands[b];
    if (!same)
        throw Error("record " + r.id + "'s bands differ from record " + out.points.front().id +
                        "'s: one morphology model holds one set of bands",
                    "", 0, "bands");
    ShapeletModel model = r.to_model();
    for (std::size_t b = 0; b < r.bands.size(); ++b) {
        // One zero point per band when every record agrees.
        if (out.band_zero_points[b] != number_or_none(r.bands[b].extra, "zero_point"))
            out.band_zero_points[b] = std::nullopt;
        model.coeffs = r.bands[b].coeffs;
        ShapeletModel aligned = rotate(model, p.alignment.rotation);
        if (p.alignment.reflected) aligned = reflect_x(aligned);
        std::vector<Complex> shape(aligned.coeffs.size());
        for (std::size_t k = 0; k < shape.size(); ++k) shape[k] = aligned.coeffs[k] / a00;
        p.band_shapes.push_back(std::move(shape));
    }
}

// The statistical part of a band's flux error: the fit's and β's share, not truncation's
// (a simulation's noise adds the first again, never the second). None when not given.
std::optional<double> statistical_flux_error(const BandCoefficients& b) {
    if (!b.flux_err || !(*b.flux_err >= 0.0)) return std::nullopt;
    const double t = number_or_none(b.extra, "flux_err_truncation").value_or(0.0);
    return std::sqrt(std::max(0.0, *b.flux_err * *b.flux_err - t * t));
}

// The band a joint record's own fields are: the one whose coefficients are the record's
// (its "band" names it too), or none.
std::optional<std::size_t> reference_band(const ShapeletRecord& r) {
    for (std::size_t b = 0; b < r.bands.size(); ++b)
        if (r.bands[b].coeffs == r.coeffs) return b;
    return std::nullopt;
}

// Each point's flux ratios, denoised (see the header); out.reference_band set.
void denoise_colours(Morphology& out, const std::vector<ShapeletRecord>& records) {
    const std::size_t bands = out.bands.size();
    const std::size_t reference = *out.reference_band;
    const Eigen::Index d = Eigen::Index(bands) - 1;
    // V has d(d+1)/2 numbers: with fewer points than d + 2 there is nothing to deconvolve.
    if (d < 1 || out.points.size() < std::size_t(d) + 2) return;
    std::vector<Eigen::VectorXd> ratios;
    std::vector<Eigen::MatrixXd> noise;
    for (std::size_t i = 0; i < out.points.size(); ++i) {
        const MorphologyPoint& p = out.points[i];
        const ShapeletRecord& r = records[i];
        if (reference_band(r) != reference)
            throw Error("record " + r.id + "'s reference band differs from record " +
                            records.front().id + "'s",
                        "", 0, "bands");
        Eigen::VectorXd x(d), sigma(d);
        bool known = true;
        for (std::size_t b = 0, k = 0; b < bands; ++b) {
            if (b == reference) continue;
            x(Eigen::Index(k)) = flux_ratio(p, b);
            const auto e = statistical_flux_error(r.bands[b]);
            known = known && e;
            sigma(Eigen::Index(k++)) = e.value_or(0.0);
        }
        const auto reference_flux = r.bands[reference].flux;
        const auto reference_error = statistical_flux_error(r.bands[reference]);
        known = known && reference_flux && *reference_flux > 0.0 && reference_error;
        Eigen::MatrixXd s = Eigen::MatrixXd::Zero(d, d);
        if (known) {
            // s_b = F_b / F_ref: Cov = (diag σ_b² + s sᵀ σ_ref²) / F_ref².
            s.diagonal() = sigma.array().square();
            s += x * x.transpose() * (*reference_error * *reference_error);
            s /= *reference_flux * *reference_flux;
        }
        ratios.push_back(std::move(x));
        noise.push_back(std::move(s));
    }
    if (std::all_of(noise.begin(), noise.end(), [](const auto& s) { return s.isZero(0.0); }))
        return;
    const GaussianPopulation population = deconvolve_gaussian(ratios, noise);
    for (std::size_t i = 0; i < out.points.size(); ++i) {
        MorphologyPoint& p = out.points[i];
        const Eigen::VectorXd moved = denoise(population, ratios[i], noise[i]) - ratios[i];
        for (std::size_t b = 0, k = 0; b < bands; ++b) {
            if (b == reference) continue;
            const double change = moved(Eigen::Index(k++));
            for (std::size_t m = 0; m < p.shape.size(); ++m)
                p.band_shapes[b][m] += change * p.shape[m];
        }
    }
}

// The points' flux ratios: mean and covariance (divided by n), the reference's row and
// column 0; out.reference_band set.
void set_colour_population(Morphology& out) {
    const std::size_t bands = out.bands.size();
    const double n = double(out.points.size());
    Eigen::VectorXd mean = Eigen::VectorXd::Zero(Eigen::Index(bands));
    std::vector<Eigen::VectorXd> ratios;
    for (const MorphologyPoint& p : out.points) {
        Eigen::VectorXd s(static_cast<Eigen::Index>(bands));
        for (std::size_t b = 0; b < bands; ++b) s(Eigen::Index(b)) = flux_ratio(p, b);
        s(Eigen::Index(*out.reference_band)) = 1.0;
        mean += s / n;
        ratios.push_back(std::move(s));
    }
    out.colour_covariance = Eigen::MatrixXd::Zero(mean.size(), mean.size());
    const Eigen::Index r = Eigen::Index(*out.reference_band);
    mean(r) = 1.0;  // exactly (a sum of n ones over n need not be)
    for (const Eigen::VectorXd& s : ratios)
        out.colour_covariance += (s - mean) * (s - mean).transpose() / n;
    out.colour_mean.assign(mean.data(), mean.data() + mean.size());
}

}  // namespace

namespace {

// A record's point: its shape aligned (ellipticity on x, a_42 phase positive) and normalised by
// a_00; its bands' shapes join `out`'s.
MorphologyPoint aligned_point(const ShapeletRecord& r, Morphology& out) {
    const ShapeletModel model = r.to_model();
    const double a00 = model.coeffs[0].real();
    if (!(a00 > 0.0)) throw Error("a_00 must be > 0 to normalise the shape", "", 0, r.id);
    if (!r.mag)
        throw Error("no magnitude (give the zero point to shapesim-decompose)", "", 0, r.id);
    MorphologyPoint p;
    p.id = r.id;
    p.n_max = r.n_max;
    p.beta = r.beta;
    p.mag = *r.mag;
    p.psf_beta = number_or_none(r.extra, "psf_beta").value_or(0.0);
    const ShapeletModel aligned = align(model, &p.alignment);
    p.shape.resize(aligned.coeffs.size());
    for (std::size_t k = 0; k < aligned.coeffs.size(); ++k) p.shape[k] = aligned.coeffs[k] / a00;
    p.shape[0] = 1.0;
    add_band_shapes(out, r, p, a00);
    return p;
}

}  // namespace

Complex adaptive_epsilon(const std::vector<Complex>& shape, int n_max, double psf_scale) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    if (n_max < 0 || shape.size() != std::size_t(polar_count(n_max)) || !(psf_scale >= 0.0))
        return {nan, nan};
    constexpr double beta_pix = 3.0;
    ShapeletModel m(0.0, 0.0, beta_pix, n_max);
    m.coeffs = shape;
    if (!(flux(m) > 0.0)) return {nan, nan};
    try {
        AdaptiveMoments a, psf;
        if (psf_scale > 0.0) {
            ShapeletModel gaussian(0.0, 0.0, beta_pix * psf_scale, 0);
            gaussian.coeffs[0] = 1.0;
            a = psf_adaptive_moments(convolve(m, gaussian));
            psf = psf_adaptive_moments(gaussian);
        } else {
            a = psf_adaptive_moments(m);
        }
        // The reference estimator's own correction (no PSF: its moments are zero).
        const std::optional<ShearEstimate> e = linear_shear_estimate(a, psf);
        return e ? e->epsilon : Complex(nan, nan);
    } catch (const Error&) {
        return {nan, nan};
    }
}

namespace {

// The nearest shape of `p` (and band shapes) whose light is nowhere below zero (positivity.hpp),
// c_{0,0} kept at 1; a shape the projection cannot keep positive in flux stays as fitted. Then
// sheared back to the fitted shape's adaptive ellipticity as seen through its PSF
// (docs/algorithms.md#positive-models): at a fixed order the nearest non-negative image of a
// small elongated galaxy is rounder.
void make_positive(MorphologyPoint& p) {
    const auto nearest = [&](const std::vector<Complex>& shape) {
        ShapeletModel m(0.0, 0.0, 1.0, p.n_max);
        m.coeffs = shape;
        return nearest_non_negative(m);
    };
    const double sum_before = even_sum(p.shape);
    const PositiveModel reference = nearest(p.shape);
    const double c00 = reference.model.coeffs[0].real();
    if (reference.iterations == 0 || !(c00 > 0.0) || !(even_sum(reference.model.coeffs) > 0.0))
        return;
    // Seen through the PSF it was fitted through (a Gaussian of its psf_beta), as the data saw
    // it: the outer light a round positive shape gains counts for more there.
    const double psf_scale = p.psf_beta > 0.0 && p.beta > 0.0 ? p.psf_beta / p.beta : 0.0;
    const Complex fitted = adaptive_epsilon(p.shape, p.n_max, psf_scale);
    for (std::size_t k = 0; k < p.shape.size(); ++k) p.shape[k] = reference.model.coeffs[k] / c00;
    p.shape[0] = 1.0;
    p.positivity_change = reference.change;
    // Each band made non-negative too, scaled to keep its flux ratio to the shape (its colour).
    const double sum = even_sum(p.shape);
    for (std::size_t b = 0; b < p.band_shapes.size(); ++b) {
        std::vector<Complex>& band = p.band_shapes[b];
        const double ratio = even_sum(band) / sum_before;
        if (ratio > 0.0) {
            const PositiveModel nearest_band = nearest(band);
            const double band_sum = even_sum(nearest_band.model.coeffs);
            if (band_sum > 0.0) {
                for (std::size_t k = 0; k < band.size(); ++k)
                    band[k] = nearest_band.model.coeffs[k] * (ratio * sum / band_sum);
                continue;
            }
        }
        for (Complex& c : band) c *= sum / sum_before;  // no light to keep positive: ratio kept
    }
    // The shear A that gives the positive shape the fitted seen ε: A ← S(ε_fit) S(−ε) A
    // from A = I, each time the positive shape projected through A afresh, until |ε − ε_fit|
    // ≤ 1e-3 (adaptive moments are not exactly covariant under a shear: a few passes). A shear
    // keeps the light non-negative (to the projection's truncation) and the area.
    if (!std::isfinite(std::abs(fitted)) || !(std::abs(fitted) < 1.0)) return;
    ShapeletModel positive(0.0, 0.0, 1.0, p.n_max);
    positive.coeffs = p.shape;
    // To 10⁻⁴ of the norm (1% of the light, as faint fits are known) and at most n_max 12, or
    // the fit's own: every mixture takes its parents' largest order, so a parent's order is
    // paid for by its mixtures (a million of them must fit in 1 GiB).
    ProjectionOptions options;
    options.tolerance = 1e-4;
    options.n_out_max = std::max(p.n_max, 12);
    Eigen::Matrix2d a = Eigen::Matrix2d::Identity();
    ShapeletModel sheared = positive;
    for (int pass = 0; pass < 6; ++pass) {
        const Complex now = adaptive_epsilon(sheared.coeffs, sheared.n_max, psf_scale);
        if (!std::isfinite(std::abs(now)) || std::abs(now - fitted) <= 1e-3) break;
        a = shear_matrix(fitted.real(), fitted.imag()) * shear_matrix(-now.real(), -now.imag()) * a;
        sheared = affine_transform(positive, a, Eigen::Vector2d::Zero(), options).model;
    }
    if (sheared.n_max == p.n_max && sheared.coeffs == p.shape) return;
    // Where the projection (cut at its order) rings below zero by more than positivity allows,
    // the sheared shape is made non-negative again, at its own order.
    if (const PositiveModel again = nearest_non_negative(sheared); again.iterations > 0 &&
        again.model.coeffs[0].real() > 0.0 && even_sum(again.model.coeffs) > 0.0)
        sheared = again.model;
    const Complex s00 = sheared.coeffs[0];
    options.n_out = sheared.n_max;
    p.shape = sheared.coeffs;
    for (Complex& c : p.shape) c /= s00;
    p.shape[0] = 1.0;
    const double sheared_sum = even_sum(p.shape);
    for (std::vector<Complex>& band : p.band_shapes) {
        ShapeletModel b(0.0, 0.0, 1.0, p.n_max);
        b.coeffs = band;
        const double ratio = even_sum(band) / sum;
        band = affine_transform(b, a, Eigen::Vector2d::Zero(), options).model.coeffs;
        const double band_sum = even_sum(band);
        for (Complex& c : band) c *= band_sum != 0.0 ? ratio * sheared_sum / band_sum : 0.0;
    }
    p.n_max = sheared.n_max;
}

// λ of every axis: k × the mean nearest-neighbour separation of the points along it, unless
// overridden; 0 for the delta-function PDF.
void set_smoothing_lengths(Morphology& out, const SmoothOptions& options) {
    SmoothingLengths& l = out.lambda;
    const double k = options.delta ? 0.0 : options.k;
    l.phase_deg = options.delta ? 0.0 : options.phase_deg;
    std::vector<double> betas, mags;
    for (const auto& p : out.points) {
        betas.push_back(p.beta);
        mags.push_back(p.mag);
    }
    l.beta =
        options.delta ? 0.0 : options.beta.value_or(k * mean_nearest_neighbour_separation(betas));
    l.mag = options.delta ? 0.0 : options.mag.value_or(k * mean_nearest_neighbour_separation(mags));
    const std::vector<PolarIndex> index = polar_indices(out.n_max);
    l.coefficient.assign(index.size(), 0.0);
    for (std::size_t i = 1; i < index.size(); ++i) {
        if (options.delta) break;
        if (options.modulus) {
            l.coefficient[i] = *options.modulus;
            continue;
        }
        std::vector<double> axis;
        for (const auto& p : out.points)
            if (i < p.shape.size())
                axis.push_back(index[i].m == 0 ? p.shape[i].real() : std::abs(p.shape[i]));
        l.coefficient[i] = k * mean_nearest_neighbour_separation(axis);
    }
}

// The records' zero point when every one has the same; none otherwise.
std::optional<double> common_zero_point(const std::vector<ShapeletRecord>& records) {
    std::optional<double> zp;
    for (const ShapeletRecord& r : records) {
        const auto z = number_or_none(r.extra, "zero_point");
        if (!z || (zp && *zp != *z)) return std::nullopt;
        if (!zp) zp = z;
    }
    return zp;
}

// The records' one frame: observed-frame models hold their image's PSF, intrinsic ones none;
// a mix is an error.
std::string common_frame(const std::vector<ShapeletRecord>& records) {
    std::string first;
    for (std::size_t k = 0; k < records.size(); ++k) {
        const Json& e = records[k].extra;
        const std::string frame =
            e.contains("frame") && e.at("frame").is_string() ? e.at("frame").get<std::string>()
                                                             : "observed";
        if (frame != "observed" && frame != "intrinsic")
            throw Error("must be \"observed\" or \"intrinsic\", got \"" + frame + "\" (record " +
                            records[k].id + ")", "", 0, "frame");
        if (k == 0)
            first = frame;
        else if (frame != first)
            throw Error("record " + records[k].id + " is " + frame + ", record " + records[0].id +
                            " " + first + ": one morphology model holds one frame",
                        "", 0, "frame");
    }
    return first;
}

}  // namespace

Morphology build_morphology(const std::vector<ShapeletRecord>& records,
                            const SmoothOptions& options) {
    options.validate();
    Morphology out;
    for (const ShapeletRecord& r : records) {
        MorphologyPoint p = aligned_point(r, out);
        out.n_max = std::max(out.n_max, p.n_max);
        out.points.push_back(std::move(p));
    }
    if (!options.delta && !options.keep_negative)
        for (MorphologyPoint& p : out.points) {
            make_positive(p);
            out.n_max = std::max(out.n_max, p.n_max);  // a shear back may raise it
        }
    if (!out.bands.empty() && out.points.size() != records.size())
        throw Error("internal: band points lost", "", 0, "bands");
    if (!out.bands.empty()) out.reference_band = reference_band(records.front());
    if (out.reference_band && !options.keep_colour_noise) denoise_colours(out, records);
    set_smoothing_lengths(out, options);
    if (!out.bands.empty()) {
        if (out.reference_band) set_colour_population(out);
        out.lambda.colour = options.delta || !out.reference_band ? 0.0 : options.colour;
    }
    out.zero_point = common_zero_point(records);
    const std::string frame = common_frame(records);
    if (!records.empty()) out.frame = frame;
    out.prepare();
    return out;
}

void Morphology::prepare() {
    colour_root = colour_covariance.size() ? symmetric_sqrt(colour_covariance) : Eigen::MatrixXd();
    for (MorphologyPoint& p : points) {
        p.modulus.resize(p.shape.size());
        p.phase.resize(p.shape.size());
        for (std::size_t k = 0; k < p.shape.size(); ++k) {
            p.modulus[k] = std::abs(p.shape[k]);
            p.phase[k] = std::arg(p.shape[k]);
        }
        ShapeletModel m(0.0, 0.0, 1.0, p.n_max);
        m.coeffs = p.shape;
        p.hole = hole_depth(m);
        const RawMoments raw = raw_moments(m);
        const double nan = std::numeric_limits<double>::quiet_NaN();
        p.adaptive_epsilon = p.n_max >= 2 ? shapesim::adaptive_epsilon(p.shape, p.n_max)
                                          : Complex(nan, nan);
        const double size2 = raw.flux > 0.0 ? raw.r2 / raw.flux : 0.0;
        p.size2 = size2 > 0.0 && std::isfinite(size2) ? size2
                                                       : std::numeric_limits<double>::quiet_NaN();
    }
    std::vector<double> counted;
    for (const MorphologyPoint& p : points)
        if (p.weight > 0.0) counted.push_back(p.mag);
    std::sort(counted.begin(), counted.end());
    for (MorphologyPoint& p : points) {
        // The nearest counted magnitude other than the point's own (one copy of it is itself).
        const auto at = std::lower_bound(counted.begin(), counted.end(), p.mag);
        const bool own = p.weight > 0.0;
        double gap = std::numeric_limits<double>::infinity();
        if (at != counted.begin()) gap = std::min(gap, p.mag - *(at - 1));
        const auto after = at + (own && at != counted.end() ? 1 : 0);
        if (after != counted.end()) gap = std::min(gap, *after - p.mag);
        p.mag_gap = gap;
    }
}

double SourceField::density(double mag_limit) const {
    const auto n = std::upper_bound(mags.begin(), mags.end(), mag_limit) - mags.begin();
    return double(n) / area_arcmin2;
}

double model_reach(double beta_pix, int n_max) {
    return beta_pix * (std::sqrt(2.0 * n_max + 1.0) + 5.0);
}

std::string drop_reason(const ShapeletRecord& r, const RecordSelection& selection) {
    // Counted under the first reason, in the order the options list them.
    for (const auto& f : selection.required)
        if (!has_any_flag(r.flags, f)) return "not " + f;
    for (const auto& f : selection.rejected)
        if (has_flag(r.flags, f)) return f;
    if (!r.mag) return "no magnitude";
    if (selection.mag_limit && *r.mag > *selection.mag_limit) return "fainter than --mag-limit";
    if (!(r.coeffs[0].real() > 0.0)) return "a_00 <= 0";
    return "";
}

namespace {

// The parent-selection weight of a kept record: 1, or its selection.weight_field (≥ 0).
double selection_weight(const ShapeletRecord& r, const RecordSelection& selection) {
    if (selection.weight_field.empty()) return 1.0;
    const auto w = optional_double(r.extra, selection.weight_field);
    if (!w || !(*w >= 0.0))
        throw Error("missing, or not a number ≥ 0", "", 0, selection.weight_field);
    return *w;
}

}  // namespace

SelectedRecords select_records(JsonlReader& reader, const RecordSelection& selection,
                               std::vector<SourceField>& fields) {
    SelectedRecords out;
    const std::vector<std::string>& images = selection.images;
    Json record;
    while (reader.next(record)) {
        ++out.read;
        ShapeletRecord r;
        try {
            r = ShapeletRecord::from_json(record);
        } catch (const Error& e) {
            throw reader.locate(e);
        }
        out.hash ^= fnv1a_64(record.dump());
        out.hash *= 0x100000001b3ULL;
        std::size_t field = 0;
        if (!images.empty()) {
            const std::string image = record.value("image", std::string());
            field = std::size_t(std::find(images.begin(), images.end(), image) - images.begin());
            if (field == images.size())
                throw reader.locate(Error(
                    "record " + r.id + " comes from '" + image + "', none of the --field images",
                    "", 0, "image"));
        }
        if (field < fields.size() && r.mag && record.value("kind", std::string("galaxy")) != "star")
            fields[field].mags.push_back(*r.mag);
        const std::string why = drop_reason(r, selection);
        if (!why.empty()) {
            ++out.dropped[why];
            continue;
        }
        double weight = 1.0;
        try {
            weight = selection_weight(r, selection);
        } catch (const Error& e) {
            throw reader.locate(e);
        }
        out.kept.push_back(std::move(r));
        out.weights.push_back(weight);
        out.field.push_back(field);
    }
    return out;
}

void weight_by_counted_area(const std::vector<SourceField>& fields,
                            const std::vector<ShapeletRecord>& kept,
                            const std::vector<std::size_t>& field, std::vector<double>& weights) {
    if (fields.size() <= 1) return;
    for (std::size_t i = 0; i < weights.size(); ++i) {
        if (field[i] >= fields.size()) continue;  // shape-only
        double area = 0.0;
        bool mine = false;
        for (std::size_t k : fields_counted(fields, *kept[i].mag)) {
            area += fields[k].area_arcmin2;
            mine = mine || k == field[i];
        }
        weights[i] = mine ? weights[i] / area : 0.0;
    }
}

void weight_by_kept_fraction(const std::vector<SourceField>& fields,
                             const std::vector<ShapeletRecord>& kept,
                             const std::vector<std::size_t>& field, std::vector<double>& weights) {
    const auto bin = [](double mag) { return long(std::floor(mag / 0.5)); };
    std::vector<std::map<long, double>> all(fields.size()), mine(fields.size());
    for (std::size_t f = 0; f < fields.size(); ++f)
        for (double mag : fields[f].mags) all[f][bin(mag)] += 1.0;
    for (std::size_t i = 0; i < kept.size(); ++i)
        if (field[i] < fields.size()) mine[field[i]][bin(*kept[i].mag)] += 1.0;
    for (std::size_t i = 0; i < kept.size(); ++i) {
        if (field[i] >= fields.size()) continue;  // shape-only
        const long b = bin(*kept[i].mag);
        const double seen = all[field[i]][b];
        if (seen > mine[field[i]][b]) weights[i] *= seen / mine[field[i]][b];
    }
}

std::vector<std::string> image_labels(const std::vector<std::string>& images) {
    std::vector<std::string> labels;
    for (const std::string& image : images) {
        std::string label = image.substr(image.find_last_of('/') + 1);
        const std::size_t fits = label.find(".fits");
        if (fits != std::string::npos) label.erase(fits, 5);
        labels.push_back(label);
    }
    for (std::size_t k = 0; k < labels.size(); ++k)
        if (std::count(labels.begin(), labels.end(), labels[k]) > 1) labels[k] = images[k];
    return labels;
}

long mark_point_fields(Morphology& morphology, const SelectedRecords& selected,
                       const RecordSelection& selection, std::size_t counted_fields) {
    const std::vector<std::string> labels = image_labels(selection.images);
    long shape_only = 0;
    for (std::size_t i = 0; i < selected.kept.size(); ++i) {
        MorphologyPoint& point = morphology.points[i];
        if (labels.size() > 1) point.id = labels[selected.field[i]] + ":" + point.id;
        point.shape_only = !selection.images.empty() && selected.field[i] >= counted_fields;
        point.weight = point.shape_only ? 0.0 : selected.weights[i];
        shape_only += point.shape_only;
    }
    return shape_only;
}

Json smooth_provenance(const std::string& input, const SelectedRecords& selected,
                       const RecordSelection& selection, const SmoothOptions& options) {
    char hex[17];
    std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(selected.hash));
    Json dropped = Json::object();
    for (const auto& [why, n] : selected.dropped) dropped[why] = n;
    return {{"program", "shapesim-smooth"},
            {"version", version()},
            {"input", input},
            {"input_records", selected.read},
            {"input_fnv1a64", hex},
            {"dropped", dropped},
            {"options",
             {{"k", options.k},
              {"lambda_phase", options.phase_deg},
              {"delta", options.delta},
              {"keep_colour_noise", options.keep_colour_noise},
              {"keep_negative", options.keep_negative},
              {"lambda_colour", options.colour},
              {"weight_left_out", selection.weight_left_out},
              {"require", selection.required},
              {"reject", selection.rejected}}}};
}

}  // namespace shapesim
