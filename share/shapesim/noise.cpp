#include "shapesim/noise.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/error.hpp"
#include "shapesim/record_fields.hpp"
#include "shapesim/statistics.hpp"

#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <ostream>

namespace shapesim {

namespace {

int side(int radius) { return 2 * radius + 1; }

// Square dilation of `blocked` (row-major ny × nx) by `grow` pixels: two 1-D passes.
std::vector<std::uint8_t> dilate(const std::vector<std::uint8_t>& blocked, long nx, long ny,
                                 int grow) {
    std::vector<std::uint8_t> rows(blocked.size(), 0), out(blocked.size(), 0);
    for (long j = 0; j < ny; ++j)
        for (long i = 0; i < nx; ++i)
            if (blocked[std::size_t(j * nx + i)])
                for (long k = std::max(0L, i - grow); k <= std::min(nx - 1, i + grow); ++k)
                    rows[std::size_t(j * nx + k)] = 1;
    for (long j = 0; j < ny; ++j)
        for (long i = 0; i < nx; ++i)
            if (rows[std::size_t(j * nx + i)])
                for (long k = std::max(0L, j - grow); k <= std::min(ny - 1, j + grow); ++k)
                    out[std::size_t(k * nx + i)] = 1;
    return out;
}

// The empirical CDF of a sample summarised by quantiles q_i at (i + ½)/Q, linear between.
double cdf_from_quantiles(const std::vector<double>& q, double x) {
    const double count = double(q.size());
    if (x < q.front()) return 0.0;
    if (x >= q.back()) return 1.0;
    const auto upper = std::upper_bound(q.begin(), q.end(), x);
    const long i = long(upper - q.begin()) - 1;  // q[i] ≤ x < q[i + 1]
    const double span = q[std::size_t(i + 1)] - q[std::size_t(i)];
    const double t = span > 0.0 ? (x - q[std::size_t(i)]) / span : 0.0;
    return (double(i) + 0.5 + t) / count;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// The marginal

void SkyMarginal::map(const float* in, float* out, long count) const {
    for (long i = 0; i < count; ++i) out[i] = float((*this)(double(in[i])));
}

void SkyMarginal::validate() const {
    auto fail = [](const std::string& why) { throw Error(why, {}, 0, "marginal"); };
    if (!(dz >= 1e-3 && dz <= 1.0)) fail("dz must be within [0.001, 1]");
    if (!(z0 >= -10.0 && z0 < 0.0)) fail("z0 must be within [-10, 0)");
    if (values.size() <= std::size_t(tail_steps) || values.size() > 20001)
        fail("must hold more than " + std::to_string(tail_steps) + " and at most 20001 values");
    for (std::size_t k = 0; k < values.size(); ++k)
        if (!(std::abs(values[k]) <= 100.0) || (k > 0 && !(values[k] > values[k - 1])))
            fail("values must be ascending, within ±100 (standard deviations)");
}

namespace {
const Fields<SkyMarginal>& marginal_fields() {
    using R = SkyMarginal;
    static const Fields<R> fields = {{"z0", &R::z0}, {"dz", &R::dz}, {"values", &R::values}};
    return fields;
}
}  // namespace

Json SkyMarginal::to_json() const {
    validate();
    Json j;
    write_fields(marginal_fields(), *this, j);
    return j;
}

SkyMarginal SkyMarginal::from_json(const Json& j) {
    if (!j.is_object()) throw Error("must be an object {z0, dz, values}", {}, 0, "marginal");
    SkyMarginal m;
    try {
        read_fields(marginal_fields(), j, m);
    } catch (const Error& e) {
        throw Error("marginal." + e.field() + ": " + e.message(), {}, 0, "marginal");
    }
    m.validate();
    return m;
}

// ---------------------------------------------------------------------------------------------
// The record

namespace {
void read_correlation_radius(NoiseRecord& r, const Json& j, NumberPairs*) {
    r.correlation.radius = required_int(j, "correlation_radius");
    if (r.correlation.radius < 0 || r.correlation.radius > 64)
        throw Error("must be within [0, 64]", {}, 0, "correlation_radius");
}
void write_correlation_radius(const NoiseRecord& r, Json& j) {
    j["correlation_radius"] = r.correlation.radius;
}
void read_correlation(NoiseRecord& r, const Json& j, NumberPairs*) {
    for (const Json& v : required_array(j, "correlation"))
        r.correlation.values.push_back(as_double(v, "correlation"));
}
void write_correlation(const NoiseRecord& r, Json& j) { j["correlation"] = r.correlation.values; }
// The quantiles and how many pixels they summarise, written when there are any.
void read_quantiles(NoiseRecord& r, const Json& j, NumberPairs*) {
    if (const Json* q = optional_array(j, "quantiles"))
        for (const Json& v : *q) r.quantiles.push_back(as_double(v, "quantiles"));
    if (auto n = optional_int(j, "quantile_pixels")) r.quantile_pixels = *n;
}
void write_quantiles(const NoiseRecord& r, Json& j) {
    if (r.quantiles.empty()) return;
    j["quantile_pixels"] = r.quantile_pixels;
    j["quantiles"] = r.quantiles;
}
void read_marginal(NoiseRecord& r, const Json& j, NumberPairs*) {
    if (j.contains("marginal")) r.marginal = SkyMarginal::from_json(j["marginal"]);
}
void write_marginal(const NoiseRecord& r, Json& j) {
    if (!r.marginal.empty()) j["marginal"] = r.marginal.to_json();
}

// The scalars, `extra`, then the arrays.
const Fields<NoiseRecord>& noise_fields() {
    using R = NoiseRecord;
    constexpr FieldPlace last = FieldPlace::after_extra;
    static const Fields<R> fields = {
        {"id", &R::id},
        {"rms", &R::rms},
        {"mad_sigma", &R::mad_sigma},
        {"pixels", &R::pixels},
        {"noise_correlation", &R::noise_correlation, FieldRule::optional},
        {"correlation_radius", read_correlation_radius, write_correlation_radius, last},
        {"correlation", read_correlation, write_correlation, last},
        {"quantile_pixels", read_quantiles, write_quantiles, last},  // with quantiles
        {"quantiles"},
        {"marginal", read_marginal, write_marginal, last},
    };
    return fields;
}
}  // namespace

NoiseRecord NoiseRecord::from_json(const Json& j) {
    return read_valid_record(noise_fields(), j);
}

void NoiseRecord::validate() const {
    auto fail = [](const char* field, const std::string& why) { throw Error(why, {}, 0, field); };
    if (!(rms > 0.0 && std::isfinite(rms))) fail("rms", "must be > 0");
    if (!(mad_sigma >= 0.0 && std::isfinite(mad_sigma))) fail("mad_sigma", "must be ≥ 0");
    if (pixels < 0) fail("pixels", "must be ≥ 0");
    if (!(noise_correlation >= 0.0)) fail("noise_correlation", "must be ≥ 0");
    const int r = correlation.radius;
    if (correlation.values.size() != std::size_t(side(r) * side(r)))
        fail("correlation", "must hold (2·correlation_radius + 1)² = " +
                                std::to_string(side(r) * side(r)) + " values, has " +
                                std::to_string(correlation.values.size()));
    if (std::abs(correlation.at(0, 0) - 1.0) > 1e-9) fail("correlation", "ξ(0, 0) must be 1");
    for (double v : correlation.values)
        if (!(std::abs(v) <= 1.0 + 1e-9)) fail("correlation", "values must be within [−1, 1]");
    if (!std::is_sorted(quantiles.begin(), quantiles.end()))
        fail("quantiles", "must be in ascending order");
    if (!marginal.empty()) marginal.validate();
}

Json NoiseRecord::to_json() const { return write_valid_record(noise_fields(), *this); }

NoiseRecord read_noise_record(const std::string& path) {
    JsonlReader reader(path, {NoiseRecord::schema});
    NoiseRecord record, more;
    if (!reader.next_record(record)) throw Error("no shapesim.noise/1 record", path);
    if (reader.next_record(more)) throw Error("more than one noise record", path);
    return record;
}

// ---------------------------------------------------------------------------------------------
// Measuring

namespace {

// The sky: pixels no masked object (S/N ≥ mask_snr: fainter ones are mostly the noise's own
// peaks) and no bad pixel reaches within `grow` pixels.
std::vector<std::uint8_t> sky_pixels(const DetectionResult& field, const SkyNoiseOptions& options) {
    const long nx = field.image.cols(), ny = field.image.rows();
    const std::size_t n = std::size_t(nx * ny);
    std::vector<std::uint8_t> blocked(n, 0);
    // Labels (index + 1) of the objects masked: those the noise alone would not make.
    std::vector<std::uint8_t> masked(field.objects.size() + 1, 0);
    for (std::size_t i = 0; i < field.objects.size(); ++i) {
        const Detection& d = field.objects[i];
        masked[i + 1] =
            !(d.flux_auto_err > 0.0) || !(d.flux_auto / d.flux_auto_err < options.mask_snr);
    }
    for (std::size_t k = 0; k < n; ++k) {
        const auto label = std::size_t(field.segmentation.data()[k]);
        blocked[k] =
            (label != 0 && (label >= masked.size() || masked[label])) || field.bad[k] != 0;
    }
    std::vector<std::uint8_t> sky = dilate(blocked, nx, ny, options.grow);
    for (auto& s : sky) s = !s;
    return sky;
}

// Clip the sky at 5 MAD-σ about its median (cosmic rays, hot pixels); the MAD σ. Error with
// fewer than 100 sky pixels.
double clip_sky(const ImageArray& image, std::vector<std::uint8_t>& sky) {
    const std::size_t n = sky.size();
    std::vector<double> values;
    for (std::size_t k = 0; k < n; ++k)
        if (sky[k]) values.push_back(image.data()[k]);
    if (values.size() < 100)
        throw Error("sky noise: only " + std::to_string(values.size()) +
                    " sky pixels away from the objects (need 100)");
    const double median = median_of_values(values);
    for (double& v : values) v = std::abs(v - median);
    const double mad_sigma = 1.4826 * median_of_values(std::move(values));
    const double cut = 5.0 * mad_sigma;
    for (std::size_t k = 0; k < n; ++k)
        if (sky[k] && !(std::abs(image.data()[k] - median) <= cut)) sky[k] = 0;
    return mad_sigma;
}

// The normalised autocorrelation ξ(dx, dy) of the centred sky pixels out to lag `r`: ξ(d) for
// dy ≥ 0 (and dx > 0 on dy = 0), the rest by symmetry, ξ(0) = 1.
NoiseCorrelation sky_autocorrelation(const std::vector<std::uint8_t>& sky,
                                     const std::vector<double>& centred, long nx, long ny, int r,
                                     double variance) {
    NoiseCorrelation xi;
    xi.radius = r;
    xi.values.assign(std::size_t(side(r) * side(r)), 0.0);
    for (int dy = 0; dy <= r; ++dy)
        for (int dx = -r; dx <= r; ++dx) {
            if (dy == 0 && dx < 0) continue;
            double pair_sum = 0.0;
            long pairs = 0;
            for (long j = 0; j + dy < ny; ++j)
                for (long i = std::max(0L, long(-dx)); i < nx && i + dx < nx; ++i) {
                    const std::size_t p = std::size_t(j * nx + i);
                    const std::size_t q = std::size_t((j + dy) * nx + i + dx);
                    if (sky[p] && sky[q]) {
                        pair_sum += centred[p] * centred[q];
                        ++pairs;
                    }
                }
            const double v = pairs > 0 ? pair_sum / double(pairs) / variance : 0.0;
            xi.values[std::size_t((dy + r) * side(r) + dx + r)] = v;
            xi.values[std::size_t((-dy + r) * side(r) - dx + r)] = v;
        }
    xi.values[std::size_t(r * side(r) + r)] = 1.0;
    return xi;
}

// Quantiles of the sky pixels on a sparse grid (every `decimate`-th pixel: neighbours are
// correlated) into `record`.
void sky_quantiles(const ImageArray& image, const std::vector<std::uint8_t>& sky,
                   const SkyNoiseOptions& options, NoiseRecord& record) {
    const long nx = image.cols(), ny = image.rows();
    std::vector<double> sparse;
    for (long j = 0; j < ny; j += options.decimate)
        for (long i = 0; i < nx; i += options.decimate)
            if (sky[std::size_t(j * nx + i)]) sparse.push_back(image.data()[j * nx + i]);
    std::sort(sparse.begin(), sparse.end());
    record.quantile_pixels = long(sparse.size());
    if (sparse.size() >= 2) {
        const int q = int(std::min<std::size_t>(std::size_t(options.quantiles), sparse.size()));
        for (int k = 0; k < q; ++k)
            record.quantiles.push_back(sorted_quantile(sparse, (double(k) + 0.5) / q));
    }
}

// The sky's standardised distribution (SkyMarginal): every sky pixel over its own σ, about
// the median, over the standard deviation; its quantiles at z0 + k·dz out to where
// `tail_pixels` lie beyond. Empty when the sky is too small for tail_steps levels a side.
SkyMarginal sky_marginal(const DetectionResult& field, const std::vector<std::uint8_t>& sky,
                         const SkyNoiseOptions& options) {
    std::vector<double> u;
    for (std::size_t k = 0; k < sky.size(); ++k) {
        const double s = field.sigma.data()[k];
        if (sky[k] && s > 0.0 && std::isfinite(s)) u.push_back(field.image.data()[k] / s);
    }
    SkyMarginal m;
    if (u.size() < 100) return m;
    std::sort(u.begin(), u.end());
    const double n = double(u.size());
    const double median = 0.5 * (u[(u.size() - 1) / 2] + u[u.size() / 2]);
    const double sd = rms_of(u);
    if (!(sd > 0.0)) return m;
    // The outermost level: Φ(z0) n ≥ tail_pixels.
    const double step = options.marginal_step;
    int levels = 0;
    while (normal_cdf(-(levels + 1) * step) * n >= double(options.marginal_tail_pixels) &&
           (levels + 1) * step <= 8.0)
        ++levels;
    if (levels <= SkyMarginal::tail_steps) return m;
    m.z0 = -levels * step;
    m.dz = step;
    for (int k = -levels; k <= levels; ++k)
        m.values.push_back((sorted_quantile(u, normal_cdf(k * step)) - median) / sd);
    // Ties (a quantised image) would make T flat: such a sky is left Gaussian.
    for (std::size_t k = 1; k < m.values.size(); ++k)
        if (!(m.values[k] > m.values[k - 1])) return SkyMarginal{};
    return m;
}

}  // namespace

NoiseRecord measure_sky_noise(const DetectionResult& field, const SkyNoiseOptions& options) {
    require(options.radius >= 0 && options.radius <= 64, "sky noise: radius must be in [0, 64]");
    require(options.grow >= 0 && options.decimate >= 1 && options.quantiles >= 2 &&
                options.mask_snr >= 0.0 && options.marginal_step > 0.0 &&
                options.marginal_tail_pixels >= 1,
            "sky noise: grow ≥ 0, decimate ≥ 1, quantiles ≥ 2, mask_snr ≥ 0, marginal_step > 0 "
            "and marginal_tail_pixels ≥ 1");
    const long nx = field.image.cols(), ny = field.image.rows();
    const std::size_t n = std::size_t(nx * ny);
    std::vector<std::uint8_t> sky = sky_pixels(field, options);
    const double mad_sigma = clip_sky(field.image, sky);

    double sum = 0.0;
    long count = 0;
    for (std::size_t k = 0; k < n; ++k)
        if (sky[k]) {
            sum += field.image.data()[k];
            ++count;
        }
    const double mean = sum / double(count);
    std::vector<double> centred(n, 0.0);
    double sum2 = 0.0;
    for (std::size_t k = 0; k < n; ++k)
        if (sky[k]) {
            centred[k] = field.image.data()[k] - mean;
            sum2 += centred[k] * centred[k];
        }
    const double variance = sum2 / double(count);
    require(variance > 0.0, "sky noise: the sky pixels are constant (no noise)");

    NoiseRecord record;
    record.rms = std::sqrt(variance);
    record.mad_sigma = mad_sigma;
    record.pixels = count;
    record.noise_correlation = field.noise_correlation;
    record.correlation = sky_autocorrelation(sky, centred, nx, ny, options.radius, variance);
    sky_quantiles(field.image, sky, options, record);
    record.marginal = sky_marginal(field, sky, options);
    return record;
}

// ---------------------------------------------------------------------------------------------
// Drawing

std::vector<double> NoiseKernel::dense() const {
    const int s = side(radius);
    std::vector<double> k(std::size_t(s * s), 0.0);
    for (std::size_t t = 0; t < columns.size(); ++t)
        for (int y = 0; y < s; ++y)
            for (int x = 0; x < s; ++x)
                k[std::size_t(y * s + x)] += columns[t][std::size_t(y)] * rows[t][std::size_t(x)];
    return k;
}

NoiseCorrelation NoiseKernel::correlation(int r) const {
    const std::vector<double> k = dense();
    const int s = side(radius);
    NoiseCorrelation xi;
    xi.radius = r;
    xi.values.assign(std::size_t(side(r) * side(r)), 0.0);
    for (int dy = -r; dy <= r; ++dy)
        for (int dx = -r; dx <= r; ++dx) {
            double v = 0.0;
            for (int y = 0; y < s; ++y)
                for (int x = 0; x < s; ++x) {
                    const int y2 = y + dy, x2 = x + dx;
                    if (y2 < 0 || y2 >= s || x2 < 0 || x2 >= s) continue;
                    v += k[std::size_t(y * s + x)] * k[std::size_t(y2 * s + x2)];
                }
            xi.values[std::size_t((dy + r) * side(r) + dx + r)] = v;
        }
    return xi;
}

NoiseKernel correlated_noise_kernel(const NoiseCorrelation& xi, double tolerance) {
    require(tolerance > 0.0 && tolerance < 1.0, "noise kernel: tolerance must be in (0, 1)");
    const int r = xi.radius;
    require(xi.values.size() == std::size_t(side(r) * side(r)), "noise kernel: bad correlation");
    if (r == 0) return drizzle_noise_kernel(1.0);
    // Grid: a power of two at least four times the correlation's width.
    int grid = 64;
    while (grid < 4 * side(r)) grid *= 2;
    std::vector<double> cosine((std::size_t(grid)));
    for (int k = 0; k < grid; ++k) cosine[std::size_t(k)] = std::cos(2.0 * pi * k / grid);
    auto phase = [&](long k) { return cosine[std::size_t(((k % grid) + grid) % grid)]; };
    // P(u, v) = Σ ξ(dx, dy) cos(2π (u dx + v dy)/N) (ξ is even), negatives set to 0; √P.
    std::vector<double> amplitude(std::size_t(grid * grid));
    double power = 0.0;
    for (int v = 0; v < grid; ++v)
        for (int u = 0; u < grid; ++u) {
            double p = 0.0;
            for (int dy = -r; dy <= r; ++dy)
                for (int dx = -r; dx <= r; ++dx)
                    p += xi.at(dx, dy) * phase(long(u) * dx + long(v) * dy);
            p = std::max(p, 0.0);
            power += p;
            amplitude[std::size_t(v * grid + u)] = std::sqrt(p);
        }
    // k(x, y) = N⁻² Σ √P cos(2π (u x + v y)/N) for |x|, |y| ≤ r; Σ_all k² = N⁻² Σ P.
    const double total = power / (double(grid) * grid);
    const int s = side(r);
    Eigen::MatrixXd k(s, s);
    for (int y = -r; y <= r; ++y)
        for (int x = -r; x <= r; ++x) {
            double value = 0.0;
            for (int v = 0; v < grid; ++v)
                for (int u = 0; u < grid; ++u)
                    value += amplitude[std::size_t(v * grid + u)] *
                             phase(long(u) * x + long(v) * y);
            k(y + r, x + r) = value / (double(grid) * grid);
        }
    // The smallest radius holding all but tolerance² of Σk²: the correlation then moves by at
    // most ≈ 2 tolerance (Cauchy–Schwarz on the pairs left out).
    int radius = r;
    for (int K = 0; K <= r; ++K) {
        const double held = k.block(r - K, r - K, side(K), side(K)).squaredNorm();
        if (held >= (1.0 - tolerance * tolerance) * total) {
            radius = K;
            break;
        }
    }
    Eigen::MatrixXd cut = k.block(r - radius, r - radius, side(radius), side(radius));
    cut /= cut.norm();
    // Separable terms by SVD, until the rest is below tolerance² of the whole.
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(cut, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const Eigen::VectorXd sv = svd.singularValues();
    const double all = sv.squaredNorm();
    NoiseKernel kernel;
    kernel.radius = radius;
    double rest = all;
    for (int t = 0; t < sv.size() && rest > tolerance * tolerance * all; ++t) {
        const Eigen::VectorXd c = svd.matrixU().col(t) * sv(t), w = svd.matrixV().col(t);
        kernel.columns.emplace_back(c.data(), c.data() + c.size());
        kernel.rows.emplace_back(w.data(), w.data() + w.size());
        rest -= sv(t) * sv(t);
    }
    // Σk² = 1 exactly for the terms kept.
    double norm2 = 0.0;
    for (double v : kernel.dense()) norm2 += v * v;
    const double scale = 1.0 / std::sqrt(norm2);
    for (auto& c : kernel.columns)
        for (double& v : c) v *= scale;
    return kernel;
}

double correlated_noise_kernel_edge(double factor) {
    require(factor >= 1.0 && std::isfinite(factor), "the correlated-noise factor must be ≥ 1");
    // F(e) = 1 + (3e + e²)/(1 + 2e²) for 4×4 block sums; it rises from 1 at e = 0 to its
    // maximum near e = 0.9.
    auto f = [](double e) { return 1.0 + (3.0 * e + e * e) / (1.0 + 2.0 * e * e); };
    if (factor == 1.0) return 0.0;
    double lo = 0.0, hi = 0.9;
    if (factor > f(hi))
        throw Error("a correlated-noise factor above " + std::to_string(f(hi)) +
                    " needs a wider kernel than 3×3: give the measured noise model "
                    "(shapesim-detect --noise-model, shapesim-render --noise-model)");
    for (int k = 0; k < 100; ++k) {
        const double mid = 0.5 * (lo + hi);
        (f(mid) < factor ? lo : hi) = mid;
    }
    return 0.5 * (lo + hi);
}

NoiseKernel drizzle_noise_kernel(double factor) {
    const double e = correlated_noise_kernel_edge(factor);
    NoiseKernel kernel;
    if (e == 0.0) {
        kernel.columns = {{1.0}};
        kernel.rows = {{1.0}};
        return kernel;
    }
    const double norm = 1.0 / std::sqrt(1.0 + 2.0 * e * e);
    kernel.radius = 1;
    kernel.columns = {{e * norm, norm, e * norm}};
    kernel.rows = kernel.columns;
    return kernel;
}

// ---------------------------------------------------------------------------------------------
// Comparing

SkyComparison compare_sky(const NoiseRecord& a, const NoiseRecord& b) {
    if (a.quantiles.size() < 2 || b.quantiles.size() < 2)
        throw Error("sky comparison: a noise record has no quantiles");
    SkyComparison c;
    c.radius = std::min(a.correlation.radius, b.correlation.radius);
    for (int dy = -c.radius; dy <= c.radius; ++dy)
        for (int dx = -c.radius; dx <= c.radius; ++dx) {
            const double d = b.correlation.at(dx, dy) - a.correlation.at(dx, dy);
            c.difference.push_back(d);
            if (std::abs(dx) <= 3 && std::abs(dy) <= 3)
                c.max_difference = std::max(c.max_difference, std::abs(d));
        }
    c.rms_ratio = b.rms / a.rms;
    // The noise about each sky's own median: a constant left by background subtraction (the
    // mesh sees the galaxies' light, which differs field to field) is not noise.
    const auto centred = [](const std::vector<double>& q, double& median) {
        const std::size_t n = q.size();
        median = n % 2 ? q[n / 2] : 0.5 * (q[n / 2 - 1] + q[n / 2]);
        std::vector<double> out = q;
        for (double& v : out) v -= median;
        return out;
    };
    double median_a = 0.0, median_b = 0.0;
    const std::vector<double> qa = centred(a.quantiles, median_a),
                              qb = centred(b.quantiles, median_b);
    c.median_offset = median_b - median_a;
    // D = sup |F_a − F_b|, over both samples' quantiles (the CDFs are linear between them).
    for (const auto* q : {&qa, &qb})
        for (double x : *q)
            c.ks_d =
                std::max(c.ks_d, std::abs(cdf_from_quantiles(qa, x) - cdf_from_quantiles(qb, x)));
    const double na = double(std::max(1L, a.quantile_pixels));
    const double nb = double(std::max(1L, b.quantile_pixels));
    const double ne = na * nb / (na + nb);
    c.ks_p = kolmogorov_q((std::sqrt(ne) + 0.12 + 0.11 / std::sqrt(ne)) * c.ks_d);
    const int percents[] = {1, 5, 95, 99};
    for (std::size_t k = 0; k < 4; ++k)
        c.percentile_ratio[k] = sky_percentile(b, percents[k]) / sky_percentile(a, percents[k]);
    return c;
}

double sky_percentile(const NoiseRecord& sky, int percent) {
    // Φ⁻¹ of 0.01 and 0.05.
    const double z1 = 2.3263478740408408, z5 = 1.6448536269514722;
    double z = 0.0;
    switch (percent) {
        case 1: z = -z1; break;
        case 5: z = -z5; break;
        case 95: z = z5; break;
        case 99: z = z1; break;
        default: require(false, "sky_percentile: 1, 5, 95 or 99");
    }
    if (sky.marginal.empty()) return std::numeric_limits<double>::quiet_NaN();
    return sky.rms * sky.marginal(z);
}

void write_sky_table(std::ostream& out, const std::vector<std::string>& names,
                     const std::vector<NoiseRecord>& skies) {
    require(!skies.empty() && names.size() == skies.size(), "sky table: names and records differ");
    static const int lags[][2] = {{1, 0}, {0, 1}, {1, 1}, {2, 0}, {2, 2}, {3, 0}, {3, 3}};
    out << "| sky | rms | MAD σ | rms/MAD σ |";
    for (const auto& l : lags) out << " ξ(" << l[0] << "," << l[1] << ") |";
    out << " max \\|Δξ\\| (≤ 3 px) | rms / ref | P1 / ref | P5 / ref | P95 / ref | P99 / ref |"
           " Δ median / rms | KS D | KS p |\n|---|---|---|---|";
    for (std::size_t k = 0; k < std::size(lags) + 9; ++k) out << "---|";
    out << "\n";
    char buf[64];
    auto put = [&](const char* format, double v) {
        std::snprintf(buf, sizeof buf, format, v);
        out << ' ' << buf << " |";
    };
    for (std::size_t k = 0; k < skies.size(); ++k) {
        const NoiseRecord& s = skies[k];
        out << "| " << names[k] << " |";
        put("%.4g", s.rms);
        put("%.4g", s.mad_sigma);
        put("%.4f", s.rms / s.mad_sigma);
        for (const auto& l : lags) put("%.3f", s.correlation.at(l[0], l[1]));
        if (k == 0) {
            out << " – | – | – | – | – | – | – | – | – |\n";
            continue;
        }
        const SkyComparison c = compare_sky(skies[0], s);
        put("%.3f", c.max_difference);
        put("%.4f", c.rms_ratio);
        for (double r : c.percentile_ratio)
            if (std::isnan(r)) out << " – |";
            else put("%.4f", r);
        put("%+.3f", c.median_offset / skies[0].rms);
        put("%.4f", c.ks_d);
        put("%.3g", c.ks_p);
        out << "\n";
    }
}

}  // namespace shapesim
