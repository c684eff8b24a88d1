#include "shapesim/measure.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/error.hpp"
#include "shapesim/exact_aperture.hpp"
#include "shapesim/polar.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

namespace shapesim {

namespace {

std::optional<double> finite(double v) {
    return std::isfinite(v) ? std::optional<double>(v) : std::nullopt;
}

// The Moffat's pixel integral: 4 × 4-point Gauss–Legendre (exact for polynomials of degree 7
// in each axis), offsets from the pixel's centre and weights summing to 1.
constexpr int moffat_points = 4;
constexpr double moffat_node[moffat_points] = {-0.4305681557970263, -0.16999052179242813,
                                               0.16999052179242813, 0.4305681557970263};
constexpr double moffat_weight[moffat_points] = {0.17392742256872692, 0.32607257743127307,
                                                 0.32607257743127307, 0.17392742256872692};

}  // namespace

MoffatFit fit_moffat(const ImageArray& image, const MaskArray& use, double x, double y,
                     double fwhm) {
    std::vector<double> px, py, value;
    for (long j = 0; j < image.rows(); ++j)
        for (long i = 0; i < image.cols(); ++i)
            if (use(j, i) && std::isfinite(image(j, i))) {
                px.push_back(double(i));
                py.push_back(double(j));
                value.push_back(image(j, i));
            }
    MoffatFit fit;
    const std::size_t n = value.size();
    if (n < 8 || !(fwhm > 0.0)) return fit;
    std::vector<double> model(n);
    // For a shape (x, y, FWHM, β): the profile's pixel integrals, then the amplitude and the
    // constant by linear least squares; the residual sum of squares.
    auto solve = [&](const std::array<double, 4>& p, double* amplitude, double* background) {
        const double w = std::exp(p[2]), beta = 1.0 + std::exp(p[3]);
        if (!(w > 0.05 && w < 1e4 && beta < 1e3)) return std::numeric_limits<double>::infinity();
        const double alpha = w / (2.0 * std::sqrt(std::pow(2.0, 1.0 / beta) - 1.0));
        const double inv_a2 = 1.0 / (alpha * alpha);
        for (std::size_t k = 0; k < n; ++k) {
            double sum = 0.0;
            for (int b = 0; b < moffat_points; ++b) {
                const double dy = py[k] + moffat_node[b] - p[1];
                double row = 0.0;
                for (int a = 0; a < moffat_points; ++a) {
                    const double dx = px[k] + moffat_node[a] - p[0];
                    row += moffat_weight[a] *
                           std::exp(-beta * std::log1p((dx * dx + dy * dy) * inv_a2));
                }
                sum += moffat_weight[b] * row;
            }
            model[k] = sum;
        }
        double smm = 0.0, sm = 0.0, sv = 0.0, smv = 0.0;
        for (std::size_t k = 0; k < n; ++k) {
            smm += model[k] * model[k];
            sm += model[k];
            sv += value[k];
            smv += model[k] * value[k];
        }
        const double det = smm * double(n) - sm * sm;
        if (!(det > 0.0)) return std::numeric_limits<double>::infinity();
        const double a = (smv * double(n) - sm * sv) / det, c = (sv - a * sm) / double(n);
        double rss = 0.0;
        for (std::size_t k = 0; k < n; ++k) {
            const double r = value[k] - a * model[k] - c;
            rss += r * r;
        }
        if (amplitude) *amplitude = a;
        if (background) *background = c;
        return rss;
    };
    // Levenberg–Marquardt on the shape (the amplitude and constant solved at each step),
    // the Jacobian by forward differences.
    std::array<double, 4> p = {x, y, std::log(fwhm), std::log(2.5)};
    auto residuals = [&](const std::array<double, 4>& q, Eigen::VectorXd& r) {
        double a = 0.0, c = 0.0;
        const double rss = solve(q, &a, &c);
        r.resize(Eigen::Index(n));
        for (std::size_t k = 0; k < n; ++k) r[Eigen::Index(k)] = value[k] - a * model[k] - c;
        return rss;
    };
    Eigen::VectorXd r0, r1;
    double cost = residuals(p, r0), lambda = 1e-3;
    bool done = false;
    for (int iteration = 0; iteration < 100 && std::isfinite(cost) && !done; ++iteration) {
        Eigen::MatrixXd jacobian(Eigen::Index(n), 4);
        const std::array<double, 4> h = {1e-4, 1e-4, 1e-5, 1e-5};
        for (int k = 0; k < 4; ++k) {
            std::array<double, 4> q = p;
            q[std::size_t(k)] += h[std::size_t(k)];
            if (!std::isfinite(residuals(q, r1))) return fit;
            jacobian.col(k) = (r1 - r0) / h[std::size_t(k)];
        }
        const Eigen::Matrix4d normal = jacobian.transpose() * jacobian;
        const Eigen::Vector4d gradient = jacobian.transpose() * r0;
        while (true) {
            Eigen::Matrix4d damped = normal;
            for (int k = 0; k < 4; ++k) damped(k, k) *= 1.0 + lambda;
            const Eigen::Vector4d step = -damped.ldlt().solve(gradient);
            std::array<double, 4> q = p;
            for (int k = 0; k < 4; ++k) q[std::size_t(k)] += step[k];
            const double trial = residuals(q, r1);
            if (trial < cost) {
                const bool small = step.cwiseAbs().maxCoeff() < 1e-8 || cost - trial < 1e-12 * cost;
                p = q;
                cost = trial;
                r0.swap(r1);
                lambda = std::max(lambda / 10.0, 1e-12);
                done = small;
                break;
            }
            lambda *= 10.0;
            if (lambda > 1e12) {
                done = true;
                break;
            }
        }
    }
    const double rss = solve(p, &fit.amplitude, &fit.background);
    fit.x = p[0];
    fit.y = p[1];
    fit.fwhm = std::exp(p[2]);
    fit.beta = 1.0 + std::exp(p[3]);
    fit.converged = std::isfinite(rss) && fit.amplitude > 0.0 &&
                    std::hypot(fit.x - x, fit.y - y) < fwhm;
    return fit;
}

MorphRecord measure_object(const DetectionResult& field, const Detection& object,
                           const SourceRecord& source, const MeasureOptions& options) {
    const long nx = field.image.cols(), ny = field.image.rows();
    // statmorph's cutout around the segment's bounding box (0-based).
    const long x0 = object.xmin - 1, y0 = object.ymin - 1;
    const long dx = object.xmax - object.xmin + 1, dy = object.ymax - object.ymin + 1;
    const long xc = x0 + dx / 2, yc = y0 + dy / 2;
    const long half = std::max(long(double(std::max(dx, dy)) * options.cutout_extent / 2.0),
                               long(options.min_cutout / 2));
    const long i0 = std::max(0L, xc - half), i1 = std::min(nx, xc + half);
    const long j0 = std::max(0L, yc - half), j1 = std::min(ny, yc + half);
    const ImageArray image = field.image.block(j0, i0, j1 - j0, i1 - i0);
    const LabelArray labels = field.segmentation.block(j0, i0, j1 - j0, i1 - i0);
    MaskArray mask(j1 - j0, i1 - i0);
    for (long j = j0; j < j1; ++j)
        for (long i = i0; i < i1; ++i) mask(j - j0, i - i0) = field.is_bad(int(j), int(i)) ? 1 : 0;
    const Morphometry m =
        measure_morphometry(image, labels, object.label, &mask, options.morphometry);

    MorphRecord r;
    r.id = source.id;
    r.x = source.x;
    r.y = source.y;
    r.mag = source.mag;
    r.fwhm = source.fwhm;
    r.a = source.a;
    r.b = source.b;
    r.theta = source.theta;
    if (source.a && source.b && source.theta && *source.a > 0.0) {
        const double a2 = *source.a * *source.a, b2 = *source.b * *source.b;
        const double e = (a2 - b2) / (a2 + b2), t = 2.0 * *source.theta * pi / 180.0;
        r.e1 = e * std::cos(t);
        r.e2 = e * std::sin(t);
    }
    r.r_petro = finite(m.r_petro);
    r.c = finite(m.concentration);
    r.a_sym = finite(m.asymmetry);
    r.s = finite(m.clumpiness());
    r.gini = finite(m.gini);
    r.m20 = finite(m.m20);
    r.flags = m.flags;
    for (const std::string& f : source.flags) r.flags.push_back(f);
    Json& e = r.extra;
    if (source.extra.contains("kind")) e["kind"] = source.extra.at("kind");
    if (source.stellarity) e["stellarity"] = *source.stellarity;
    auto put = [&](const char* key, double v) {
        if (std::isfinite(v)) e[key] = v;
    };
    put("r20", m.r20);
    put("r80", m.r80);
    put("smoothness", m.smoothness);
    put("sky_sigma", m.sky_sigma);
    put("x_asym", m.x_asymmetry + double(i0) + 1.0);
    put("y_asym", m.y_asymmetry + double(j0) + 1.0);
    const double snr = object.flux_auto_err > 0.0 ? object.flux_auto / object.flux_auto_err : 0.0;
    put("snr", snr);

    if (options.aperture_radius > 0.0) {
        // SExtractor's MAG_APER: the background-subtracted pixels inside the circle, each
        // weighted by its area inside; bad pixels count as zero.
        double flux = 0.0;
        visit_circle_rows(int(nx), int(ny), source.x - 1.0, source.y - 1.0, options.aperture_radius,
                          [&](int j, int begin, int end, const double* weights) {
                              for (int i = begin; i < end; ++i)
                                  if (!field.is_bad(j, i) && std::isfinite(field.image(j, i)))
                                      flux += weights[i - begin] * field.image(j, i);
                          });
        e["flux_aper"] = flux;
        if (flux > 0.0) e["mag_aper"] = options.zero_point - 2.5 * std::log10(flux);
    }
    if (options.fit_star_profile && e.contains("kind") && e["kind"] == "star" && source.fwhm) {
        // The box of ±3 FWHM about the centroid: the star's own pixels and the sky's, not a
        // neighbour's nor a bad one.
        const double w = std::max(*source.fwhm, 1.0);
        const long h = long(std::ceil(3.0 * w));
        const long cx = long(std::lround(source.x - 1.0)), cy = long(std::lround(source.y - 1.0));
        const long b0 = std::max(0L, cx - h), b1 = std::min(nx, cx + h + 1);
        const long c0 = std::max(0L, cy - h), c1 = std::min(ny, cy + h + 1);
        if (b1 > b0 && c1 > c0) {
            const ImageArray box = field.image.block(c0, b0, c1 - c0, b1 - b0);
            MaskArray use(c1 - c0, b1 - b0);
            for (long j = c0; j < c1; ++j)
                for (long i = b0; i < b1; ++i) {
                    const auto label = field.segmentation(j, i);
                    use(j - c0, i - b0) =
                        !field.is_bad(int(j), int(i)) && (label == 0 || label == object.label);
                }
            const MoffatFit fit = fit_moffat(box, use, source.x - 1.0 - double(b0),
                                             source.y - 1.0 - double(c0), w);
            if (fit.converged) {
                e["fwhm_moffat"] = fit.fwhm;
                e["beta_moffat"] = fit.beta;
            } else {
                r.flags.push_back("moffat_failed");
            }
        }
    }

    if ((options.shear_psf || options.shear_psf_field) &&
        !(e.contains("kind") && e["kind"] == "star")) {
        // The PSF where the galaxy is, when it varies across the image.
        const AdaptiveMoments psf =
            options.shear_psf_field
                ? psf_adaptive_moments(to_polar(options.shear_psf_field->at(source.x, source.y)))
                : *options.shear_psf;
        // Adaptive moments on the cutout, other objects' and bad pixels left out, from the
        // detection's centre and size.
        MaskArray other(labels.rows(), labels.cols());
        for (long j = 0; j < labels.rows(); ++j)
            for (long i = 0; i < labels.cols(); ++i)
                other(j, i) = mask(j, i) || (labels(j, i) != 0 && labels(j, i) != object.label);
        const double sigma0 = source.a && source.b && *source.a > 0.0 && *source.b > 0.0
                                  ? std::sqrt(*source.a * *source.b)
                                  : std::sqrt(psf.trace() / 2.0);
        std::string why;
        const auto am = adaptive_moments(image, &other, source.x - 1.0 - double(i0),
                                         source.y - 1.0 - double(j0), std::max(sigma0, 0.5), &why);
        const auto estimate = am ? linear_shear_estimate(*am, psf) : std::nullopt;
        if (estimate) {
            e["shear_e1"] = estimate->epsilon.real();
            e["shear_e2"] = estimate->epsilon.imag();
            e["shear_resolution"] = estimate->resolution;
            e["shear_sigma"] = std::sqrt(std::sqrt(am->m11 * am->m22 - am->m12 * am->m12));
        } else {
            r.flags.push_back("shear_failed");
            e["shear_why"] = am ? "no larger than the PSF" : why;
        }
    }

    // Reliability.
    if (!(m.r_petro >= options.min_petrosian)) r.flags.push_back("small");
    if (snr < options.min_snr) r.flags.push_back("faint");
    if (std::isfinite(m.r_petro)) {
        const double radius = options.morphometry.petro_extent * m.r_petro;
        long inside = 0, other = 0;
        // hypot(dx, dy) ≥ |dx| and ≥ |dy| (faithfully rounded, as glibc's is): rows and columns
        // farther than the radius are left out before it is computed.
        for (long j = 0; j < labels.rows(); ++j) {
            const double dy = double(j) - m.y_asymmetry;
            if (std::abs(dy) > radius) continue;
            for (long i = 0; i < labels.cols(); ++i) {
                const double dx = double(i) - m.x_asymmetry;
                if (std::abs(dx) > radius || std::hypot(dx, dy) > radius) continue;
                ++inside;
                if (labels(j, i) != 0 && labels(j, i) != object.label) ++other;
            }
        }
        if (inside > 0 && double(other) > options.max_neighbour_fraction * double(inside))
            r.flags.push_back("crowded");
    }
    return r;
}

}  // namespace shapesim
