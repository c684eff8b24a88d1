#include "shapesim/moments.hpp"

#include "shapesim/basis1d.hpp"
#include "shapesim/error.hpp"

#include <cmath>
#include <limits>

namespace shapesim {

namespace {
constexpr double kSqrtPi = 1.77245385090551602730;     // √π
constexpr double kSqrt2Pi = 2.50662827463100050242;    // √(2π)
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

void require_sized(const ShapeletModel& model) {
    require(model.n_max >= 0 && int(model.coeffs.size()) == polar_count(model.n_max),
            "moments: coefficient count does not match n_max");
}

void require_sized(const CartesianModel& model) {
    require(model.n_max >= 0 && model.b.rows() == model.n_max + 1 &&
                model.b.cols() == model.n_max + 1,
            "moments: Cartesian matrix does not match n_max");
}
}  // namespace

double flux(const ShapeletModel& model) {
    require_sized(model);
    double sum = 0.0;
    for (int n = 0; n <= model.n_max; n += 2) sum += model.at(n, 0).real();
    return 2.0 * kSqrtPi * model.beta_pix * sum;
}

double squared_norm(const ShapeletModel& model) {
    require_sized(model);
    // Σ over all m of |a_{n,m}|², with a_{n,−m} = conj a_{n,m} counted once for each sign.
    double sum = 0.0;
    int k = 0;
    for (const auto& [n, m] : polar_indices(model.n_max)) {
        (void)n;
        sum += (m == 0 ? 1.0 : 2.0) * std::norm(model.coeffs[k++]);
    }
    return sum;
}

double squared_norm(const CartesianModel& model) {
    require_sized(model);
    double sum = 0.0;
    for (int n1 = 0; n1 <= model.n_max; ++n1)
        for (int n2 = 0; n1 + n2 <= model.n_max; ++n2) sum += model.b(n1, n2) * model.b(n1, n2);
    return sum;
}

RawMoments raw_moments(const ShapeletModel& model) {
    require_sized(model);
    const double beta = model.beta_pix;
    RawMoments raw;
    double flux_sum = 0.0, r2_sum = 0.0;
    Complex z_sum, z2_sum;
    for (int n = 0; n <= model.n_max; ++n) {
        if (n % 2 == 0) {
            const double a0 = model.at(n, 0).real();
            flux_sum += a0;
            r2_sum += (n + 1.0) * a0;
            if (n >= 2) z2_sum += std::sqrt(double(n) * (n + 2.0)) * std::conj(model.at(n, 2));
        } else {
            z_sum += std::sqrt(n + 1.0) * std::conj(model.at(n, 1));
        }
    }
    raw.flux = 2.0 * kSqrtPi * beta * flux_sum;
    raw.z = 2.0 * kSqrt2Pi * beta * beta * z_sum;
    raw.r2 = 4.0 * kSqrtPi * beta * beta * beta * r2_sum;
    raw.z2 = 4.0 * kSqrtPi * beta * beta * beta * z2_sum;
    return raw;
}

RawMoments raw_moments(const CartesianModel& model) {
    require_sized(model);
    // S_pq = ∫ x^p y^q f = β^{p+q+1} Σ b(n1, n2) M_p(n1) M_q(n2).
    const Eigen::MatrixXd mom = hermite_moments(2, model.n_max);
    const Eigen::MatrixXd mb = mom * model.b;              // (p, n2) = Σ_{n1} M_p(n1) b(n1, n2)
    const Eigen::MatrixXd s = mb * mom.transpose();        // (p, q)
    const double beta = model.beta_pix;
    const double b1 = beta, b2 = beta * beta, b3 = b2 * beta;
    RawMoments raw;
    raw.flux = b1 * s(0, 0);
    raw.z = b2 * Complex(s(1, 0), s(0, 1));
    raw.r2 = b3 * (s(2, 0) + s(0, 2));
    raw.z2 = b3 * Complex(s(2, 0) - s(0, 2), 2.0 * s(1, 1));
    return raw;
}

Moments moments_from_raw(const RawMoments& raw, double x_c, double y_c) {
    Moments out;
    out.flux = raw.flux;
    if (!(raw.flux > 0.0) || !std::isfinite(raw.flux)) {
        // Centroid and shape are undefined without positive flux (moments.hpp).
        out.dx = out.dy = out.x = out.y = kNaN;
        out.q11 = out.q22 = out.q12 = out.r2_about_centre = out.rms_radius = kNaN;
        out.chi = out.epsilon = Complex(kNaN, kNaN);
        return out;
    }
    const Complex centroid = raw.z / raw.flux;
    out.dx = centroid.real();
    out.dy = centroid.imag();
    out.x = x_c + out.dx;
    out.y = y_c + out.dy;
    out.r2_about_centre = raw.r2 / raw.flux;
    const double trace = out.r2_about_centre - std::norm(centroid);  // Q11 + Q22
    const Complex traceless = raw.z2 / raw.flux - centroid * centroid;  // Q11 − Q22 + 2i Q12
    out.q11 = 0.5 * (trace + traceless.real());
    out.q22 = 0.5 * (trace - traceless.real());
    out.q12 = 0.5 * traceless.imag();
    if (!(trace > 0.0)) {
        out.rms_radius = kNaN;
        out.chi = out.epsilon = Complex(kNaN, kNaN);
        return out;
    }
    out.rms_radius = std::sqrt(trace);
    out.chi = traceless / trace;
    const double chi2 = std::norm(out.chi);
    out.epsilon = chi2 < 1.0 ? out.chi / (1.0 + std::sqrt(1.0 - chi2)) : Complex(kNaN, kNaN);
    return out;
}

Moments moments(const ShapeletModel& model) {
    return moments_from_raw(raw_moments(model), model.x, model.y);
}

Moments moments(const CartesianModel& model) {
    return moments_from_raw(raw_moments(model), model.x, model.y);
}

}  // namespace shapesim
