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

// Σ_{n even} Re c_{n,0}: a shape's flux over 2√π β a_{0,0}.
double even_sum(const std::vector<Complex>& shape) {
    double sum = 0.0;
    int k = 0;
    for (int n = 0; k < int(shape.size()); ++n)
        for (int m = n % 2; m <= n && k < int(shape.size()); m += 2, ++k)
            if (m == 0 && n % 2 == 0) sum += shape[std::size_t(k)].real();
    return sum;
}

}  // namespace

double flux_ratio(const MorphologyPoint& p, std::size_t band) {
    const double sum = even_sum(p.shape);
    return sum != 0.0 ? even_sum(p.band_shapes.at(band)) / sum : std::numeric_limits<double>::quiet_NaN();
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
    if (std::all_of(noise.begin(), noise.end(), [](const auto& s) { return s.isZero(0.0); })) return;
    const GaussianPopulation population = deconvolve_gaussian(ratios, noise);
    for (std::size_t i = 0; i < out.points.size(); ++i) {
        MorphologyPoint& p = out.points[i];
        const Eigen::VectorXd moved = denoise(population, ratios[i], noise[i]) - ratios[i];
        for (std::size_t b = 0, k = 0; b < bands; ++b) {
            if (b == reference) continue;
            const double change = moved(Eigen::Index(k++));
            for (std::size_t m = 0; m < p.shape.size(); ++m) p.band_shapes[b][m] += change * p.shape[m];
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

// The nearest shape of `p` (and band shapes) whose light is nowhere below zero (positivity.hpp),
// c_{0,0} kept at 1; a shape the projection cannot keep positive in flux stays as fitted.
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
    l.beta = options.delta ? 0.0 : options.beta.value_or(k * mean_nearest_neighbour_separation(betas));
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
        for (MorphologyPoint& p : out.points) make_positive(p);
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

std::vector<std::size_t> fields_counted(const std::vector<SourceField>& fields, double mag) {
    double deepest = -std::numeric_limits<double>::infinity();
    for (const SourceField& f : fields) deepest = std::max(deepest, f.completeness);
    std::vector<std::size_t> counted;
    for (std::size_t k = 0; k < fields.size(); ++k)
        if (fields[k].completeness >= std::min(mag, deepest)) counted.push_back(k);
    return counted;
}

long count_shape_only(const Morphology& morphology) {
    return long(std::count_if(morphology.points.begin(), morphology.points.end(),
                              [](const MorphologyPoint& p) { return p.shape_only; }));
}

double field_density(const std::vector<SourceField>& fields, double mag_limit) {
    if (fields.empty()) return 0.0;
    if (fields.size() == 1) return fields.front().density(mag_limit);
    double brightest = mag_limit;
    for (const SourceField& f : fields)
        if (!f.mags.empty()) brightest = std::min(brightest, f.mags.front());
    constexpr double width = 0.25;
    double density = 0.0;
    // Bins (lo, hi] from just below the brightest galaxy up to the limit.
    for (double lo = std::floor(brightest / width) * width - width; lo < mag_limit; lo += width) {
        const double hi = std::min(lo + width, mag_limit);
        double count = 0.0, area = 0.0;
        for (std::size_t k : fields_counted(fields, hi)) {
            const auto& m = fields[k].mags;
            count += double(std::upper_bound(m.begin(), m.end(), hi) -
                            std::upper_bound(m.begin(), m.end(), lo));
            area += fields[k].area_arcmin2;
        }
        if (area > 0.0) density += count / area;
    }
    return density;
}

double count_turnover(const std::vector<double>& sorted_mags) {
    if (sorted_mags.size() < 10) return std::numeric_limits<double>::infinity();
    constexpr double width = 0.5;
    std::map<long, long> bins;
    for (double m : sorted_mags) ++bins[long(std::floor(m / width))];
    long best = bins.begin()->first, most = 0;
    for (const auto& [bin, n] : bins)
        if (n > most) {
            most = n;
            best = bin;
        }
    return double(best + 1) * width;
}

double power_law_magnitude(double u, double slope, double lo, double hi) {
    const double span = hi - lo;
    const double k = slope * std::log(10.0);
    if (std::abs(k * span) < 1e-9) return lo + u * span;
    // N(< m) ∝ e^{k (m − lo)} − 1, inverted.
    return lo + std::log1p(u * std::expm1(k * span)) / k;
}

namespace {

// ∫_lo^hi e^{k (m − pivot)} dm and ∫_lo^hi (m − pivot) e^{k (m − pivot)} dm, with their limits
// as k → 0.
struct PowerMoments {
    double zeroth = 0.0, first = 0.0;
};
PowerMoments power_moments(double k, double lo, double hi, double pivot) {
    const double a = lo - pivot, b = hi - pivot;
    if (std::abs(k) * std::max(std::abs(a), std::abs(b)) < 1e-7)
        return {b - a, 0.5 * (b * b - a * a)};
    const double ea = std::exp(k * a), eb = std::exp(k * b);
    // ∫ x e^{kx} dx = e^{kx} (x/k − 1/k²)
    return {(eb - ea) / k, eb * (b / k - 1.0 / (k * k)) - ea * (a / k - 1.0 / (k * k))};
}

}  // namespace

double CountModel::density(double lo, double hi) const {
    lo = std::max(lo, bright);
    hi = std::min(hi, faint);
    if (!(hi > lo)) return 0.0;
    return std::pow(10.0, log_density) * power_moments(slope * std::log(10.0), lo, hi, pivot).zeroth;
}

CountModel fit_counts(const std::vector<SourceField>& fields, double bright, double faint) {
    CountModel c;
    c.bright = bright;
    c.faint = faint;
    struct Range {
        double area, hi;
    };
    std::vector<Range> ranges;
    double sum = 0.0, first = std::numeric_limits<double>::infinity(), last = -first;
    for (const SourceField& f : fields) {
        const double hi = std::min(faint, f.completeness);
        if (!(hi > bright) || !(f.area_arcmin2 > 0.0)) continue;
        ranges.push_back({f.area_arcmin2, hi});
        for (double m : f.mags)
            if (m >= bright && m <= hi) {
                ++c.galaxies;
                sum += m - c.pivot;
                first = std::min(first, m);
                last = std::max(last, m);
            }
    }
    if (c.galaxies < 2 || !(last > first))
        throw Error("the fields hold " + std::to_string(c.galaxies) +
                    " galaxies of distinct magnitudes between " + std::to_string(bright) + " and " +
                    std::to_string(faint) + ": too few to fit counts to");
    const double mean = sum / double(c.galaxies);
    const double ln10 = std::log(10.0);
    // The mean magnitude (less the pivot) the power law of slope b predicts over the ranges,
    // weighted by area; it rises with b, so bisection finds the score's root.
    const auto predicted = [&](double b) {
        double zeroth = 0.0, first_moment = 0.0;
        for (const Range& r : ranges) {
            const PowerMoments m = power_moments(b * ln10, bright, r.hi, c.pivot);
            zeroth += r.area * m.zeroth;
            first_moment += r.area * m.first;
        }
        return std::make_pair(zeroth, first_moment / zeroth);
    };
    double lo = -3.0, hi = 3.0;
    for (int i = 0; i < 200 && hi - lo > 1e-13; ++i) {
        const double mid = 0.5 * (lo + hi);
        (predicted(mid).second < mean ? lo : hi) = mid;
    }
    c.slope = 0.5 * (lo + hi);
    c.log_density = std::log10(double(c.galaxies) / predicted(c.slope).first);
    return c;
}

Json Morphology::to_json() const {
    Json doc = Json::object();
    doc["schema"] = schema;
    doc["n_max"] = n_max;
    if (zero_point) doc["zero_point"] = *zero_point;
    if (frame != "observed") doc["frame"] = frame;
    Json lam = Json::object();
    lam["phase_deg"] = lambda.phase_deg;
    lam["beta"] = lambda.beta;
    lam["mag"] = lambda.mag;
    lam["coefficient"] = lambda.coefficient;
    if (!bands.empty()) lam["colour"] = lambda.colour;
    doc["lambda"] = lam;
    if (!bands.empty()) {
        Json list = Json::array();
        for (std::size_t b = 0; b < bands.size(); ++b) {
            Json j = {{"band", bands[b]}};
            if (band_zero_points[b]) j["zero_point"] = *band_zero_points[b];
            list.push_back(std::move(j));
        }
        doc["bands"] = std::move(list);
        if (reference_band) {
            Json covariance = Json::array();
            for (Eigen::Index i = 0; i < colour_covariance.rows(); ++i) {
                Json row = Json::array();
                for (Eigen::Index j = 0; j < colour_covariance.cols(); ++j)
                    row.push_back(colour_covariance(i, j));
                covariance.push_back(std::move(row));
            }
            doc["colours"] = {{"reference", bands[*reference_band]},
                              {"mean", colour_mean},
                              {"covariance", std::move(covariance)}};
        }
    }
    Json pts = Json::array();
    for (const auto& p : points) {
        Json shape = Json::array();
        for (const Complex& c : p.shape) shape.push_back(Json::array({c.real(), c.imag()}));
        pts.push_back({{"id", p.id},
                       {"n_max", p.n_max},
                       {"beta", p.beta},
                       {"mag", p.mag},
                       {"weight", p.weight},
                       {"rotation", p.alignment.rotation},
                       {"reflected", p.alignment.reflected},
                       {"shape", shape}});
        if (p.psf_beta > 0.0) pts.back()["psf_beta"] = p.psf_beta;
        if (p.positivity_change > 0.0) pts.back()["positivity_change"] = p.positivity_change;
        if (!p.band_shapes.empty()) {
            Json list = Json::array();
            for (const auto& band : p.band_shapes) {
                Json pairs = Json::array();
                for (const Complex& c : band) pairs.push_back(Json::array({c.real(), c.imag()}));
                list.push_back(std::move(pairs));
            }
            pts.back()["bands"] = std::move(list);
        }
        if (p.shape_only) pts.back()["shape_only"] = true;
    }
    doc["points"] = pts;
    if (!source_fields.empty()) {
        Json fields = Json::array();
        for (const SourceField& f : source_fields) {
            Json j = {{"area_arcmin2", f.area_arcmin2}, {"mags", f.mags}};
            if (!f.image.empty()) j["image"] = f.image;
            if (std::isfinite(f.completeness)) j["completeness"] = f.completeness;
            if (f.star_mags) j["star_mags"] = *f.star_mags;
            fields.push_back(std::move(j));
        }
        // One plain field keeps the first version's form.
        if (source_fields.size() == 1 && source_fields[0].image.empty() &&
            !std::isfinite(source_fields[0].completeness))
            doc["source_field"] = fields[0];
        else
            doc["source_fields"] = fields;
    }
    if (!shape_fields.empty()) doc["shape_fields"] = shape_fields;
    doc["provenance"] = provenance;
    return doc;
}

namespace {

double number(const Json& object, const char* field, const std::string& where) {
    if (!object.is_object() || !object.contains(field) || !object.at(field).is_number())
        throw Error("missing or not a number", "", 0, where + field);
    const double v = object.at(field).get<double>();
    if (!std::isfinite(v)) throw Error("not finite", "", 0, where + field);
    return v;
}

// "colours": {"reference": band, "mean": [one per band], "covariance": [[…] one row per band]}.
void read_colour_population(Morphology& m, const Json& colours) {
    const std::size_t n = m.bands.size();
    if (!colours.is_object() || !colours.contains("reference") || !colours.at("reference").is_string())
        throw Error("missing or not a string", "", 0, "colours.reference");
    const auto at = std::find(m.bands.begin(), m.bands.end(), colours.at("reference").get<std::string>());
    if (at == m.bands.end()) throw Error("not one of the bands", "", 0, "colours.reference");
    m.reference_band = std::size_t(at - m.bands.begin());
    const auto numbers = [](const Json& list, std::size_t size, const std::string& where) {
        if (!list.is_array() || list.size() != size)
            throw Error("must be an array of one number per band", "", 0, where);
        std::vector<double> out;
        for (const Json& v : list) {
            if (!v.is_number() || !std::isfinite(v.get<double>())) throw Error("not a finite number", "", 0, where);
            out.push_back(v.get<double>());
        }
        return out;
    };
    m.colour_mean = numbers(colours.contains("mean") ? colours.at("mean") : Json(), n, "colours.mean");
    const Json& rows = colours.contains("covariance") ? colours.at("covariance") : Json();
    if (!rows.is_array() || rows.size() != n)
        throw Error("must hold one row per band", "", 0, "colours.covariance");
    m.colour_covariance.resize(Eigen::Index(n), Eigen::Index(n));
    for (std::size_t i = 0; i < n; ++i) {
        const std::vector<double> row = numbers(rows[i], n, "colours.covariance");
        for (std::size_t j = 0; j < n; ++j) m.colour_covariance(Eigen::Index(i), Eigen::Index(j)) = row[j];
    }
    if (!m.colour_covariance.isApprox(m.colour_covariance.transpose()))
        throw Error("must be symmetric", "", 0, "colours.covariance");
}

}  // namespace

namespace {

// Shape coefficients as [re, im] pairs of finite numbers; errors name `field`.
std::vector<Complex> read_complex_pairs(const Json& list, const std::string& field) {
    std::vector<Complex> shape;
    for (const Json& c : list) {
        if (!c.is_array() || c.size() != 2 || !c[0].is_number() || !c[1].is_number())
            throw Error("must hold [re, im] pairs of numbers", "", 0, field);
        const Complex v(c[0].get<double>(), c[1].get<double>());
        if (!std::isfinite(v.real()) || !std::isfinite(v.imag()))
            throw Error("not finite", "", 0, field);
        shape.push_back(v);
    }
    return shape;
}

// "lambda": the smoothing lengths (its colour width is the bands', read with them).
void read_lambda(const Json& doc, Morphology& m) {
    if (!doc.contains("lambda")) throw Error("missing", "", 0, "lambda");
    const Json& lam = doc.at("lambda");
    m.lambda.phase_deg = number(lam, "phase_deg", "lambda.");
    m.lambda.beta = number(lam, "beta", "lambda.");
    m.lambda.mag = number(lam, "mag", "lambda.");
    if (!lam.contains("coefficient") || !lam.at("coefficient").is_array() ||
        lam.at("coefficient").size() != std::size_t(polar_count(m.n_max)))
        throw Error("must be an array of polar_count(n_max) numbers", "", 0, "lambda.coefficient");
    for (const Json& v : lam.at("coefficient")) {
        if (!v.is_number() || !(v.get<double>() >= 0.0))
            throw Error("must be numbers ≥ 0", "", 0, "lambda.coefficient");
        m.lambda.coefficient.push_back(v.get<double>());
    }
    if (m.lambda.phase_deg < 0 || m.lambda.beta < 0 || m.lambda.mag < 0)
        throw Error("smoothing lengths must be ≥ 0", "", 0, "lambda");
}

// A multi-band model's "bands", their colour kernel's width and the colour population.
void read_bands(const Json& doc, Morphology& m) {
    const Json& list = doc.at("bands");
    const Json& lam = doc.at("lambda");
    if (!list.is_array() || list.empty()) throw Error("must be a non-empty array", "", 0, "bands");
    for (std::size_t b = 0; b < list.size(); ++b) {
        const std::string where = "bands[" + std::to_string(b) + "]";
        if (!list[b].is_object() || !list[b].contains("band") || !list[b].at("band").is_string())
            throw Error("missing or not a string", "", 0, where + ".band");
        m.bands.push_back(list[b].at("band").get<std::string>());
        m.band_zero_points.push_back(list[b].contains("zero_point")
                                         ? std::optional(number(list[b], "zero_point", where + "."))
                                         : std::nullopt);
    }
    if (lam.contains("colour") && lam.at("colour").is_array())
        throw Error(
            "is one width per band: a model of an older shapesim-smooth (smooth its "
            "records again)",
            "", 0, "lambda.colour");
    m.lambda.colour = number(lam, "colour", "lambda.");
    if (m.lambda.colour < 0.0) throw Error("must be ≥ 0", "", 0, "lambda.colour");
    if (doc.contains("colours")) read_colour_population(m, doc.at("colours"));
}

// One of "points" (`where`: "points[i]."), checked against the model's n_max and bands.
MorphologyPoint read_point(const Json& pj, const std::string& where, const Morphology& m) {
    MorphologyPoint p;
    if (!pj.is_object() || !pj.contains("id") || !pj.at("id").is_string())
        throw Error("missing or not a string", "", 0, where + "id");
    p.id = pj.at("id").get<std::string>();
    p.n_max = int(number(pj, "n_max", where));
    if (p.n_max < 0 || p.n_max > m.n_max)
        throw Error("must be in [0, n_max of the model]", "", 0, where + "n_max");
    p.beta = number(pj, "beta", where);
    if (!(p.beta > 0.0)) throw Error("must be > 0", "", 0, where + "beta");
    p.mag = number(pj, "mag", where);
    p.weight = pj.contains("weight") ? number(pj, "weight", where) : 1.0;
    p.psf_beta = pj.contains("psf_beta") ? number(pj, "psf_beta", where) : 0.0;
    p.positivity_change =
        pj.contains("positivity_change") ? number(pj, "positivity_change", where) : 0.0;
    if (!(p.psf_beta >= 0.0)) throw Error("must be ≥ 0", "", 0, where + "psf_beta");
    if (!(p.weight >= 0.0)) throw Error("must be ≥ 0", "", 0, where + "weight");
    p.alignment.rotation = pj.contains("rotation") ? number(pj, "rotation", where) : 0.0;
    p.alignment.reflected = pj.value("reflected", false);
    if (pj.contains("shape_only")) {
        if (!pj.at("shape_only").is_boolean())
            throw Error("must be true or false", "", 0, where + "shape_only");
        p.shape_only = pj.at("shape_only").get<bool>();
        if (p.shape_only && p.weight != 0.0)
            throw Error("a shape-only point must have weight 0", "", 0, where + "weight");
    }
    if (!pj.contains("shape") || !pj.at("shape").is_array() ||
        pj.at("shape").size() != std::size_t(polar_count(p.n_max)))
        throw Error("must hold polar_count(n_max) [re, im] pairs", "", 0, where + "shape");
    p.shape = read_complex_pairs(pj.at("shape"), where + "shape");
    if (m.bands.empty()) return p;
    const Json* list = pj.contains("bands") ? &pj.at("bands") : nullptr;
    if (!list || !list->is_array() || list->size() != m.bands.size())
        throw Error("must hold one shape per band", "", 0, where + "bands");
    for (const Json& band : *list) {
        if (!band.is_array() || band.size() != p.shape.size())
            throw Error("must hold polar_count(n_max) [re, im] pairs per band", "", 0,
                        where + "bands");
        p.band_shapes.push_back(read_complex_pairs(band, where + "bands"));
    }
    return p;
}

// A source field (`where`: "source_fields[k]"); its magnitudes sorted.
SourceField read_source_field(const Json& f, const std::string& where) {
    SourceField field;
    if (!f.is_object()) throw Error("must be an object", "", 0, where);
    field.area_arcmin2 = number(f, "area_arcmin2", where + ".");
    if (!(field.area_arcmin2 > 0.0)) throw Error("must be > 0", "", 0, where + ".area_arcmin2");
    if (!f.contains("mags") || !f.at("mags").is_array())
        throw Error("must be an array of numbers", "", 0, where + ".mags");
    for (const Json& v : f.at("mags")) {
        if (!v.is_number() || !std::isfinite(v.get<double>()))
            throw Error("must be finite numbers", "", 0, where + ".mags");
        field.mags.push_back(v.get<double>());
    }
    std::sort(field.mags.begin(), field.mags.end());
    if (f.contains("image")) {
        if (!f.at("image").is_string()) throw Error("must be a string", "", 0, where + ".image");
        field.image = f.at("image").get<std::string>();
    }
    if (f.contains("completeness")) field.completeness = number(f, "completeness", where + ".");
    if (f.contains("star_mags")) {
        if (!f.at("star_mags").is_array())
            throw Error("must be an array of numbers", "", 0, where + ".star_mags");
        std::vector<double> stars;
        for (const Json& v : f.at("star_mags")) {
            if (!v.is_number() || !std::isfinite(v.get<double>()))
                throw Error("must be finite numbers", "", 0, where + ".star_mags");
            stars.push_back(v.get<double>());
        }
        std::sort(stars.begin(), stars.end());
        field.star_mags = std::move(stars);
    }
    return field;
}

// The real fields: "source_field" (one, of older models), "source_fields", "shape_fields".
void read_fields(const Json& doc, Morphology& m) {
    if (doc.contains("source_field"))
        m.source_fields.push_back(read_source_field(doc.at("source_field"), "source_field"));
    if (doc.contains("source_fields")) {
        if (!doc.at("source_fields").is_array())
            throw Error("must be an array", "", 0, "source_fields");
        std::size_t k = 0;
        for (const Json& f : doc.at("source_fields"))
            m.source_fields.push_back(
                read_source_field(f, "source_fields[" + std::to_string(k++) + "]"));
    }
    if (doc.contains("shape_fields")) {
        const Json& f = doc.at("shape_fields");
        if (!f.is_array()) throw Error("must be an array of strings", "", 0, "shape_fields");
        for (const Json& image : f) {
            if (!image.is_string()) throw Error("must be an array of strings", "", 0, "shape_fields");
            m.shape_fields.push_back(image.get<std::string>());
        }
    }
}

}  // namespace

Morphology Morphology::from_json(const Json& doc) {
    if (!doc.is_object() || !doc.contains("schema") || doc.at("schema") != schema)
        throw Error(std::string("not a morphology model (expected schema \"") + schema + "\")", "",
                    0, "schema");
    Morphology m;
    // Checked as a number before it becomes an int (1e13 or NaN would not fit one).
    const double n_max = number(doc, "n_max", "");
    if (!(n_max > -1.0 && n_max < 101.0)) throw Error("must be in [0, 100]", "", 0, "n_max");
    m.n_max = int(n_max);
    if (doc.contains("zero_point") && !doc.at("zero_point").is_null())
        m.zero_point = number(doc, "zero_point", "");
    if (doc.contains("frame")) {
        if (!doc.at("frame").is_string() ||
            (doc.at("frame") != "observed" && doc.at("frame") != "intrinsic"))
            throw Error("must be \"observed\" or \"intrinsic\"", "", 0, "frame");
        m.frame = doc.at("frame").get<std::string>();
    }
    read_lambda(doc, m);
    if (doc.contains("bands")) read_bands(doc, m);
    if (!doc.contains("points") || !doc.at("points").is_array() || doc.at("points").empty())
        throw Error("must be a non-empty array", "", 0, "points");
    std::size_t i = 0;
    for (const Json& pj : doc.at("points"))
        m.points.push_back(read_point(pj, "points[" + std::to_string(i++) + "].", m));
    read_fields(doc, m);
    if (doc.contains("provenance")) m.provenance = doc.at("provenance");
    m.prepare();
    return m;
}

Morphology Morphology::read(const std::string& path) {
    std::ifstream file;
    std::istream* in = &std::cin;
    if (path != "-") {
        file.open(path);
        if (!file) throw Error("cannot open", path);
        in = &file;
    }
    std::stringstream text;
    text << in->rdbuf();
    const Json doc = parse_json_document(text.str(), path);
    try {
        return from_json(doc);
    } catch (const Error& e) {
        throw e.at(path, 0);
    }
}

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

double conditional_mag_spread(const MorphologyPoint& p, double lambda_mag, const DrawOptions& draw) {
    const double gap = std::isfinite(p.mag_gap) ? p.mag_gap : 0.0;
    return std::max(lambda_mag, std::min(gap, 0.5 * draw.max_mag_shift));
}

namespace {

// The window [lo, hi) of `order` (sorted by magnitude) holding the `k` parents nearest in
// magnitude to `mag` that lie within `max_shift` of it (the nearest always qualifies).
std::pair<std::size_t, std::size_t> magnitude_window(const Morphology& morphology,
                                                     const std::vector<std::size_t>& order,
                                                     double mag, std::size_t k, double max_shift) {
    k = std::min(k, order.size());
    const auto at = [&](std::size_t i) { return morphology.points[order[i]].mag; };
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
            out.shape[k] = Complex(c.real() + shrink * l.coefficient[k] * stream.epanechnikov(), 0.0);
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
    const double peak_ratio = std::pow(10.0, -0.4 * (mag - p.mag)) * (p.beta / beta) * (p.beta / beta);
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

// A conditional draw as a mixture: a magnitude (fitted counts, or a parent's smoothed), its
// shape parent near it in magnitude, the mixture, a rotation and a reflection.
DrawnGalaxy draw_mixture(const Morphology& morphology, const std::vector<double>& parents,
                         RandomStream& stream, double pixel_scale, double zero_point,
                         double mag_limit, const DrawOptions& draw) {
    DrawnGalaxy g;
    const double u = stream.uniform() * parents.back();
    const std::size_t mag_parent = parent_at(parents, u);
    if (draw.counts) {
        g.mag = draw.counts->magnitude(u / parents.back());
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
    const double u = stream.uniform() * parents.back();
    g.parent = parent_at(parents, u);
    // Magnitudes from the fitted counts: drawn once (the same deviate), the shape parent the
    // only parent.
    const bool counted = conditional && draw.counts.has_value();
    if (counted) {
        g.mag = draw.counts->magnitude(u / parents.back());
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
