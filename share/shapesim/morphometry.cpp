#include "shapesim/morphometry.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/error.hpp"
#include "shapesim/exact_aperture.hpp"
#include "shapesim/lane_math.hpp"
#include "shapesim/optimize.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <limits>
#include <numeric>
#include <type_traits>

namespace shapesim {

namespace {

// bad_pixels' outlier test of one pixel v from its eight neighbours (the row above left to
// right, the two beside it, the row below): |v − m| > n_σ s, m and s² = m₂ − m² their mean and
// variance.
bool is_outlier(double v, const std::array<double, 8>& neighbours, double n_sigma) {
    double m = 0.0, m2 = 0.0;
    for (const double w : neighbours) {
        m += w / 8.0;
        m2 += w * w / 8.0;
    }
    return std::abs(v - m) > n_sigma * std::sqrt(m2 - m * m);
}

// The outlier test of bad_pixels for pixels here[0 … count), away from the stamp's edges (rows
// above and below, columns either side): out[i] = |v − m| > n_σ s, m and s² = m₂ − m² the mean
// and variance of the eight neighbours, summed in the same order in lanes or not (the same
// bits), four pixels a lane group. Compiled for AVX2 and for the baseline (outliers chooses).
__attribute__((always_inline)) inline void outliers_lanes(const double* above, const double* here,
                                                         const double* below, long count,
                                                         double n_sigma, std::uint8_t* out) {
    using lane::Doubles4;
    long i = 0;
    for (; i + 4 <= count; i += 4) {
        Doubles4 m = {}, m2 = {};
        for (const double* p : {above - 1, above, above + 1, here - 1, here + 1, below - 1, below,
                                below + 1}) {
            Doubles4 w;
            std::memcpy(&w, p + i, sizeof w);
            m += w / 8.0;
            m2 += w * w / 8.0;
        }
        Doubles4 v;
        std::memcpy(&v, here + i, sizeof v);
        const lane::Mask4 outlier = lane::abs(v - m) > n_sigma * lane::sqrt(m2 - m * m);
        for (int k = 0; k < 4; ++k) out[i + k] = outlier[k] != 0;
    }
    for (; i < count; ++i)
        out[i] = is_outlier(here[i],
                            {above[i - 1], above[i], above[i + 1], here[i - 1], here[i + 1],
                             below[i - 1], below[i], below[i + 1]},
                            n_sigma);
}

__attribute__((target("avx2"))) void outliers_avx2(const double* above, const double* here,
                                                   const double* below, long count,
                                                   double n_sigma, std::uint8_t* out) {
    outliers_lanes(above, here, below, count, n_sigma, out);
}

void outliers(const double* above, const double* here, const double* below, long count,
              double n_sigma, std::uint8_t* out) {
    if (lane::have_avx2())
        outliers_avx2(above, here, below, count, n_sigma, out);
    else
        outliers_lanes(above, here, below, count, n_sigma, out);
}

}  // namespace

// Outliers are cosmic rays and hot pixels.
detail::PixelFlags detail::bad_pixels(const ImageArray& image, const LabelArray& labels,
                                      int label, const MaskArray* mask, double n_sigma) {
    const long ny = image.rows(), nx = image.cols();
    PixelFlags masked(ny, nx);
    thread_local std::vector<std::uint8_t> outlier;  // a row's, away from the edges
    outlier.resize(std::size_t(nx));
    for (long j = 0; j < ny; ++j) {
        const bool inner_row = n_sigma > 0.0 && j > 0 && j + 1 < ny && nx > 2;
        if (inner_row)
            outliers(&image(j - 1, 1), &image(j, 1), &image(j + 1, 1), nx - 2, n_sigma,
                     outlier.data() + 1);
        for (long i = 0; i < nx; ++i) {
            const double v = image(j, i);
            bool bad = (labels(j, i) != 0 && labels(j, i) != label) || (mask && (*mask)(j, i)) ||
                       !std::isfinite(v);
            if (!bad && inner_row && i > 0 && i + 1 < nx) {
                bad = outlier[std::size_t(i)] != 0;
            } else if (!bad && n_sigma > 0.0) {  // on the edge: neighbours clamped to the stamp
                std::array<double, 8> neighbours;
                std::size_t n = 0;
                for (long dj = -1; dj <= 1; ++dj)
                    for (long di = -1; di <= 1; ++di)
                        if (dj || di)
                            neighbours[n++] = image(std::clamp(j + dj, 0L, ny - 1),
                                                    std::clamp(i + di, 0L, nx - 1));
                bad = is_outlier(v, neighbours, n_sigma);
            }
            masked(j, i) = bad;
        }
    }
    return masked;
}

namespace {

constexpr double nan = std::numeric_limits<double>::quiet_NaN();

using Grid = Eigen::Array<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Exact aperture sums (sep's with subpix 0, exact_aperture.hpp) on a stamp; centres in 0-based
// pixel coordinates.
class Apertures {
public:
    explicit Apertures(const Grid& image)
        : image_(image), w_(int(image.cols())), h_(int(image.rows())) {}
    double circle(double x, double y, double r) const {
        return sum_circle(image_.data(), w_, h_, x, y, r);
    }
    double annulus(double x, double y, double r_in, double r_out) const {
        return circle(x, y, r_out) - circle(x, y, std::max(r_in, 0.0));
    }
    // The ellipse of semi-axes (a, a/q) at angle θ.
    double ellipse(double x, double y, double a, double q, double theta) const {
        return sum_ellipse(image_.data(), w_, h_, x, y, a, a / q, theta);
    }
    double ellipse_annulus(double x, double y, double a_in, double a_out, double q,
                           double theta) const {
        return ellipse(x, y, a_out, q, theta) - ellipse(x, y, std::max(a_in, 0.0), q, theta);
    }

private:
    const Grid& image_;
    int w_, h_;
};

// The first root of `f` walking outward over `points` radii from `lo` to `hi` (f > 0 inside),
// refined by brent_root (optimize.hpp); `lo` when f < 0 already there, `hi` when f never
// turns negative.
double first_root(const std::function<double(double)>& f, double lo, double hi, int points,
                  bool* bracketed) {
    double r_prev = lo, v_prev = 0.0;
    *bracketed = true;
    for (int k = 0; k < points; ++k) {
        const double r = lo + (hi - lo) * k / (points - 1);
        const double v = f(r);
        if (v == 0.0) return r;
        if (v < 0.0) {
            if (k == 0) {
                *bracketed = false;
                return lo;
            }
            return brent_root(f, r_prev, r, v_prev, v, 1e-6);
        }
        r_prev = r;
        v_prev = v;
    }
    *bracketed = false;
    return hi;
}

// scipy.ndimage-style 'reflect' index (half-sample symmetric: … c b a | a b c …).
long reflect(long i, long n) {
    while (i < 0 || i >= n) {
        if (i < 0) i = -i - 1;
        if (i >= n) i = 2 * n - i - 1;
    }
    return i;
}

// A separable filter with weights w[0..K) over offsets first..first+K−1, reflecting edges.
// Each output is 0 + w[0]·v₀ + w[1]·v₁ + … in this order; the loops run over k outside and
// the pixels inside (contiguous: Eigen vectorises them, each lane the same product and sum).
Grid separable_filter(const Grid& in, const std::vector<double>& w, long first) {
    const long ny = in.rows(), nx = in.cols(), taps = long(w.size());
    Grid rows = Grid::Zero(ny, nx), out = Grid::Zero(ny, nx);
    if (nx == 0 || ny == 0) return out;
    std::vector<double> padded(std::size_t(nx + taps - 1));  // a row, reflected at both ends
    for (long j = 0; j < ny; ++j) {
        for (long t = 0; t < nx + taps - 1; ++t)
            padded[std::size_t(t)] = in(j, reflect(t + first, nx));
        Eigen::Map<Eigen::ArrayXd> row(rows.data() + j * nx, nx);
        for (long k = 0; k < taps; ++k)
            row += w[std::size_t(k)] * Eigen::Map<const Eigen::ArrayXd>(padded.data() + k, nx);
    }
    for (long j = 0; j < ny; ++j) {
        Eigen::Map<Eigen::ArrayXd> row(out.data() + j * nx, nx);
        for (long k = 0; k < taps; ++k) {
            const double* src = rows.data() + reflect(j + first + k, ny) * nx;
            row += w[std::size_t(k)] * Eigen::Map<const Eigen::ArrayXd>(src, nx);
        }
    }
    return out;
}

// k × k mean filter (scipy uniform_filter: window i − k/2 … i + k − k/2 − 1).
Grid boxcar(const Grid& in, int k) {
    if (k <= 1) return in;
    return separable_filter(in, std::vector<double>(std::size_t(k), 1.0 / k), -long(k / 2));
}

// Gaussian filter of σ (scipy gaussian_filter: radius ⌊4σ + ½⌋, normalised weights).
Grid gaussian(const Grid& in, double sigma) {
    if (!(sigma > 0.0)) return in;
    const long radius = long(4.0 * sigma + 0.5);
    std::vector<double> w;
    double sum = 0.0;
    for (long d = -radius; d <= radius; ++d) {
        w.push_back(std::exp(-0.5 * double(d * d) / (sigma * sigma)));
        sum += w.back();
    }
    for (double& v : w) v /= sum;
    return separable_filter(in, w, -radius);
}

using Mask = detail::PixelFlags;
using Centre = std::array<double, 2>;

// A flag of the measurement, once, in the order the steps raise them.
void add_flag(Morphometry& out, const std::string& f) {
    if (std::find(out.flags.begin(), out.flags.end(), f) == out.flags.end()) out.flags.push_back(f);
}

using detail::bad_pixels;

// The first-moment centre of the segment's light `zs` (of total `total`).
Centre centroid(const Grid& zs, double total) {
    double sx = 0.0, sy = 0.0;
    for (long j = 0; j < zs.rows(); ++j)
        for (long i = 0; i < zs.cols(); ++i) {
            sx += double(i) * zs(j, i);
            sy += double(j) * zs(j, i);
        }
    return {sx / total, sy / total};
}

// The sky box, for the sky terms of A and S: the first square of only sky and no user mask, in
// row order, of side `size`, then half that, … (down to 4); `out.sky_box` its side (0: none).
Grid find_sky_box(const Grid& z, const LabelArray& labels, const MaskArray* mask, int size,
                  Morphometry& out) {
    const long ny = z.rows(), nx = z.cols();
    // dirty(j, i): the segment or user-mask pixels above and left of (j, i), so that a box's
    // count is four look-ups.
    Eigen::Array<long, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> dirty(ny + 1, nx + 1);
    dirty.row(0).setZero();
    dirty.col(0).setZero();
    for (long j = 0; j < ny; ++j)
        for (long i = 0; i < nx; ++i)
            dirty(j + 1, i + 1) = dirty(j, i + 1) + dirty(j + 1, i) - dirty(j, i) +
                                  (labels(j, i) != 0 || (mask && (*mask)(j, i)) ? 1 : 0);
    Grid sky;
    for (; size > 2 && out.sky_box == 0; size /= 2)
        for (long j = 0; j + size < ny && out.sky_box == 0; ++j)
            for (long i = 0; i + size < nx; ++i) {
                const long count = dirty(j + size, i + size) - dirty(j, i + size) -
                                   dirty(j + size, i) + dirty(j, i);
                if (count == 0) {
                    out.sky_box = size;
                    sky = z.block(j, i, size, size);
                    break;
                }
            }
    return sky;
}

// The sky's mean and rms into `out`, and its own asymmetry per pixel (the noise's share of A);
// without a sky box, NaN, "no_sky" and 0.
double sky_statistics(const Grid& sky, Morphometry& out) {
    if (out.sky_box == 0) {
        out.sky_mean = out.sky_sigma = nan;
        add_flag(out, "no_sky");
        return 0.0;
    }
    out.sky_mean = sky.mean();
    out.sky_sigma = std::sqrt((sky - out.sky_mean).square().mean());
    const Grid flipped = sky.reverse();
    return (flipped - sky).abs().sum() / double(sky.size());
}

// The Petrosian ratio's root: the annulus' mean surface brightness over the disc's, less η.
double petrosian_ratio(double disc, double ring, double eta) {
    const double ratio = disc == 0.0 ? (ring != 0.0 ? 1.0 : 0.0) : std::abs(ring) / std::abs(disc);
    return ratio - eta;
}

// The circular Petrosian radius about (x, y), searched out to `r_max`; "petrosian_unbracketed"
// where the ratio never crosses η.
double circular_petrosian(const Apertures& on_z, double x, double y, double r_max,
                          const MorphometryOptions& options, Morphometry& out) {
    const double w = options.annulus_width;
    auto f = [&](double r) {
        const double disc = on_z.circle(x, y, r) / (pi * r * r);
        const double r_in = r - 0.5 * w, r_out = r + 0.5 * w;
        const double ring = on_z.annulus(x, y, r_in, r_out) / (pi * (r_out * r_out - r_in * r_in));
        return petrosian_ratio(disc, ring, options.eta);
    };
    bool ok = false;
    const double r = first_root(f, w, r_max, 100, &ok);
    if (!ok) add_flag(out, "petrosian_unbracketed");
    return r;
}

// Elongation and orientation from the second moments of `zs` about `centre`, regularised (as
// SExtractor does) so that a point source's are defined.
void shape_about(const Grid& zs, double total, const Centre& centre, Morphometry& out) {
    double x2 = 0.0, y2 = 0.0, xy = 0.0;
    for (long j = 0; j < zs.rows(); ++j)
        for (long i = 0; i < zs.cols(); ++i) {
            const double dx = double(i) - centre[0], dy = double(j) - centre[1];
            x2 += dx * dx * zs(j, i);
            y2 += dy * dy * zs(j, i);
            xy += dx * dy * zs(j, i);
        }
    x2 /= total;
    y2 /= total;
    xy /= total;
    while (std::abs(x2 * y2 - xy * xy) < 1.0 / 144.0) {
        x2 += x2 >= 0.0 ? 1.0 / 12.0 : -1.0 / 12.0;
        y2 += y2 >= 0.0 ? 1.0 / 12.0 : -1.0 / 12.0;
    }
    const double mean = 0.5 * (x2 + y2), diff = std::sqrt(0.25 * (x2 - y2) * (x2 - y2) + xy * xy);
    double l1 = mean + diff, l2 = mean - diff;
    if (std::abs(l2) > std::abs(l1)) std::swap(l1, l2);
    out.elongation = std::sqrt(std::abs(l1)) / std::sqrt(std::abs(l2));
    out.orientation = 0.5 * std::atan2(2.0 * xy, x2 - y2);
}

// r20, r50, r80 of the light within petro_extent × r_p, and C = 5 log₁₀(r80 / r20).
void measure_concentration(const Apertures& on_z, const Centre& centre,
                           const MorphometryOptions& options, Morphometry& out) {
    const double r_total = options.petro_extent * out.r_petro;
    double flux_total = on_z.circle(centre[0], centre[1], r_total);
    if (flux_total == 0.0) {
        add_flag(out, "concentration_no_flux");
        out.r20 = out.r50 = out.r80 = out.concentration = nan;
        return;
    }
    flux_total = std::abs(flux_total);
    // The three searches walk the same radii: each radius' flux is measured once.
    std::array<double, 100> walked;
    int known = 0;  // walked[1 .. known] hold |flux| within r_total·k/99
    auto radius_of = [&](double fraction) {
        auto flux = [&](double r) {
            return r > 0.0 ? std::abs(on_z.circle(centre[0], centre[1], r)) : 0.0;
        };
        auto g = [&](double r) { return flux(r) / flux_total - fraction; };
        double prev = 0.0, g_prev = g(prev);
        for (int k = 1; k < 100; ++k) {
            const double r = r_total * k / 99.0;
            if (k > known) {
                walked[std::size_t(k)] = flux(r);
                known = k;
            }
            const double g_r = walked[std::size_t(k)] / flux_total - fraction;
            if (g_r > 0.0) return brent_root(g, prev, r, g_prev, g_r, 1e-6);
            prev = r;
            g_prev = g_r;
        }
        return r_total;
    };
    out.r20 = radius_of(0.2);
    out.r50 = radius_of(0.5);
    out.r80 = radius_of(0.8);
    out.concentration = out.r20 > 0.0 ? 5.0 * std::log10(out.r80 / out.r20) : nan;
}

// The smoothness S: the light above a boxcar-smoothed copy in the annulus between
// petro_fraction_cas and petro_extent × r_p, less the sky's share, over the light there.
void measure_smoothness(const Grid& z, const Apertures& on_z, const Grid& sky, const Centre& centre,
                        const MorphometryOptions& options, Morphometry& out) {
    // statmorph's k = ⌊0.25 r_p⌋; an even k puts the window half a pixel off centre, which
    // reads a gradient as clumps and makes S depend on the orientation: made odd unless
    // statmorph's own is asked for.
    int k = int(options.petro_fraction_cas * out.r_petro);
    if (!options.statmorph_boxcar && k % 2 == 0 && k > 0) k += 1;
    const Grid smooth = boxcar(z, k);
    const Grid residual = (z - smooth).max(0.0);
    const double r_in = options.petro_fraction_cas * out.r_petro,
                 r_out = options.petro_extent * out.r_petro;
    const double flux = on_z.annulus(centre[0], centre[1], r_in, r_out);
    const double s_diff = Apertures(residual).annulus(centre[0], centre[1], r_in, r_out);
    double sky_term = 0.0;
    if (out.sky_box > 0) {
        const Grid sky_smooth = boxcar(sky, k);
        sky_term = (sky - sky_smooth).max(0.0).sum() / double(sky.size());
    }
    const double area = pi * (r_out * r_out - r_in * r_in);
    out.smoothness = flux > 0.0 ? (s_diff - area * sky_term) / flux : nan;
    if (!std::isfinite(out.smoothness)) add_flag(out, "smoothness_undefined");
}

// The elliptical Petrosian radius (semi-major axis) about `centre`, of the shape's elongation
// and orientation, searched out to `a_max`; "petrosian_ellip_unbracketed" where it never
// crosses η.
double elliptical_petrosian(const Apertures& on_z, const Centre& centre, double a_max,
                            const MorphometryOptions& options, Morphometry& out) {
    const double q = out.elongation, theta = out.orientation, w = options.annulus_width;
    auto f = [&](double a) {
        const double disc = on_z.ellipse(centre[0], centre[1], a, q, theta) / (pi * a * a / q);
        const double a_in = a - 0.5 * w, a_out = a + 0.5 * w;
        const double ring = on_z.ellipse_annulus(centre[0], centre[1], a_in, a_out, q, theta) /
                            (pi * (a_out * a_out - a_in * a_in) / q);
        return petrosian_ratio(disc, ring, options.eta);
    };
    bool ok = false;
    const double a = first_root(f, w, a_max, 100, &ok);
    if (!ok) add_flag(out, "petrosian_ellip_unbracketed");
    return a;
}

using Segment = Eigen::Array<std::uint8_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// The Gini segment (statmorph): the 8-connected region, holding the (first) maximum, of the
// image smoothed by a Gaussian of petro_fraction_gini × r_p(ellip) above that smoothed image's
// mean surface brightness in the elliptical Petrosian annulus about the centroid.
Segment gini_segment(const Grid& z, const MorphometryOptions& options, const Morphometry& out) {
    const long ny = z.rows(), nx = z.cols();
    const double q = out.elongation, theta = out.orientation, w = options.annulus_width;
    const Grid smooth = gaussian(z, options.petro_fraction_gini * out.r_petro_ellip);
    const double a_in = out.r_petro_ellip - 0.5 * w, a_out = out.r_petro_ellip + 0.5 * w;
    const double threshold =
        Apertures(smooth).ellipse_annulus(out.x_centroid, out.y_centroid, a_in, a_out, q, theta) /
        (pi * (a_out * a_out - a_in * a_in) / q);
    Segment in(ny, nx);
    in.setZero();
    Eigen::Index mj = 0, mi = 0;
    smooth.maxCoeff(&mj, &mi);
    if (!(smooth(mj, mi) >= threshold)) return in;
    std::vector<std::pair<long, long>> stack{{long(mj), long(mi)}};
    in(mj, mi) = 1;
    while (!stack.empty()) {
        const auto [j, i] = stack.back();
        stack.pop_back();
        for (long dj = -1; dj <= 1; ++dj)
            for (long di = -1; di <= 1; ++di) {
                const long jj = j + dj, ii = i + di;
                if (jj < 0 || ii < 0 || jj >= ny || ii >= nx || in(jj, ii)) continue;
                if (smooth(jj, ii) >= threshold) {
                    in(jj, ii) = 1;
                    stack.push_back({jj, ii});
                }
            }
    }
    return in;
}

// The Gini coefficient of |z| over the segment's pixels (Lotz et al. 2004, eq. 6).
double gini_of(const Grid& z, const Segment& in) {
    std::vector<double> values;
    for (long j = 0; j < z.rows(); ++j)
        for (long i = 0; i < z.cols(); ++i)
            if (in(j, i)) values.push_back(std::abs(z(j, i)));
    std::sort(values.begin(), values.end());
    const double n = double(values.size());
    double num = 0.0, sum = 0.0;
    for (std::size_t k = 0; k < values.size(); ++k) {
        num += (2.0 * double(k + 1) - n - 1.0) * values[k];
        sum += values[k];
    }
    return sum > 0.0 ? num / ((n - 1.0) * sum) : nan;
}

// M20 (Lotz et al. 2004): log₁₀ of the second moment of the brightest 20% of the segment's light
// over the whole's, both about the first-moment centre of the segment's light.
double m20_of(const Grid& z, const Segment& in) {
    const long ny = z.rows(), nx = z.cols();
    Grid y(ny, nx);
    double yt = 0.0, yx = 0.0, yy = 0.0;
    for (long j = 0; j < ny; ++j)
        for (long i = 0; i < nx; ++i) {
            y(j, i) = in(j, i) ? z(j, i) : 0.0;
            yt += y(j, i);
            yx += double(i) * y(j, i);
            yy += double(j) * y(j, i);
        }
    const double cx = yx / yt, cy = yy / yt;
    double m_total = 0.0;
    for (long j = 0; j < ny; ++j)
        for (long i = 0; i < nx; ++i)
            m_total += y(j, i) *
                       ((double(i) - cx) * (double(i) - cx) + (double(j) - cy) * (double(j) - cy));
    // The cut: the value at which the ascending cumulative sum reaches 80% of the total, else
    // the largest value. Zeros (most of the stamp) are left out of the sort: adding one leaves
    // the sum and its test as they were, so the cut is never one, unless it is the largest value
    // (and the cut only serves in y ≥ cut, where 0 and −0 are alike).
    std::vector<double> all;
    bool zero = false;
    for (long k = 0; k < y.size(); ++k) {
        if (y.data()[k] != 0.0)
            all.push_back(y.data()[k]);
        else
            zero = true;
    }
    std::sort(all.begin(), all.end());
    double cumulative = 0.0;
    double cut = all.empty() ? 0.0 : (zero ? std::max(all.back(), 0.0) : all.back());
    for (double v : all) {
        cumulative += v;
        if (cumulative / yt >= 0.8) {
            cut = v;
            break;
        }
    }
    double m_bright = 0.0;
    for (long j = 0; j < ny; ++j)
        for (long i = 0; i < nx; ++i)
            if (y(j, i) >= cut)
                m_bright += y(j, i) * ((double(i) - cx) * (double(i) - cx) +
                                       (double(j) - cy) * (double(j) - cy));
    return (m_bright > 0.0 && m_total > 0.0) ? std::log10(m_bright / m_total) : nan;
}

}  // namespace

Morphometry measure_morphometry(const ImageArray& image, const LabelArray& labels, int label,
                                const MaskArray* mask, const MorphometryOptions& options) {
    const long ny = image.rows(), nx = image.cols();
    require(labels.rows() == ny && labels.cols() == nx, "segmentation and image differ in size");
    require(!mask || (mask->rows() == ny && mask->cols() == nx), "mask and image differ in size");
    Morphometry out;

    // z: the stamp with its bad pixels zeroed; zs: the segment's own light.
    const Mask masked = bad_pixels(image, labels, label, mask, options.n_sigma_outlier);
    Grid z(ny, nx), zs(ny, nx);
    for (long j = 0; j < ny; ++j)
        for (long i = 0; i < nx; ++i) {
            z(j, i) = masked(j, i) ? 0.0 : image(j, i);
            zs(j, i) = labels(j, i) == label ? z(j, i) : 0.0;
        }
    const double total = zs.sum();
    require(total > 0.0, "the segment has no positive flux");
    const Centre centroid_at = centroid(zs, total);
    out.x_centroid = centroid_at[0];
    out.y_centroid = centroid_at[1];

    const Grid sky = find_sky_box(z, labels, mask, options.skybox_size, out);
    const double sky_asymmetry = sky_statistics(sky, out);

    const Apertures on_z(z);
    const double diagonal = std::sqrt(double(nx * nx + ny * ny));
    out.r_petro_centroid =
        circular_petrosian(on_z, out.x_centroid, out.y_centroid, diagonal, options, out);

    // Asymmetry about its own minimum, aperture fixed at 1.5 r_p(centroid).
    const detail::AsymmetryCentre asymmetry = detail::minimise_asymmetry(
        z, masked, options.petro_extent * out.r_petro_centroid, sky_asymmetry, centroid_at);
    if (asymmetry.left_stamp) add_flag(out, "asymmetry_centre_left_stamp");
    const Centre centre = asymmetry.centre;
    out.x_asymmetry = centre[0];
    out.y_asymmetry = centre[1];
    out.asymmetry = asymmetry.asymmetry;

    // The rest about the asymmetry centre.
    shape_about(zs, total, centre, out);
    out.r_petro = circular_petrosian(on_z, centre[0], centre[1], diagonal, options, out);
    measure_concentration(on_z, centre, options, out);
    measure_smoothness(z, on_z, sky, centre, options, out);
    out.r_petro_ellip = elliptical_petrosian(on_z, centre, diagonal * out.elongation, options, out);
    const Segment in = gini_segment(z, options, out);
    const long count = long(in.cast<long>().sum());
    if (count <= 1 || count == nx * ny) {
        add_flag(out, "gini_segment_bad");
        out.gini = out.m20 = nan;
        return out;
    }
    out.gini = gini_of(z, in);
    out.m20 = m20_of(z, in);
    if (!std::isfinite(out.m20)) add_flag(out, "m20_undefined");
    return out;
}

}  // namespace shapesim
