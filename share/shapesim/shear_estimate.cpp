#include "shapesim/shear_estimate.hpp"

#include "shapesim/error.hpp"
#include "shapesim/render.hpp"

#include <algorithm>
#include <cmath>

namespace shapesim {

std::optional<AdaptiveMoments> adaptive_moments(const ImageArray& image, const MaskArray* mask,
                                                double x0, double y0, double sigma0,
                                                std::string* why) {
    auto fail = [&](const char* reason) {
        if (why) *why = reason;
        return std::nullopt;
    };
    require(!mask || (mask->rows() == image.rows() && mask->cols() == image.cols()),
            "adaptive moments: the mask must be the image's size");
    if (!(sigma0 > 0.0) || !std::isfinite(x0) || !std::isfinite(y0)) return fail("no start");
    const long nx = long(image.cols()), ny = long(image.rows());
    double m11 = sigma0 * sigma0, m22 = m11, m12 = 0.0;
    for (int pass = 1; pass <= 200; ++pass) {
        const double det = m11 * m22 - m12 * m12;
        if (!(det > 0.0) || !(m11 > 0.0)) return fail("the weight is not positive definite");
        const double i11 = m22 / det, i22 = m11 / det, i12 = -m12 / det;
        // The weight's 5σ box along each axis (its support to e^-12.5).
        const double hx = 5.0 * std::sqrt(m11), hy = 5.0 * std::sqrt(m22);
        if (!(hx < double(nx) && hy < double(ny))) return fail("the weight outgrew the image");
        const long i0 = std::max(0L, long(std::floor(x0 - hx))),
                   i1 = std::min(nx - 1, long(std::ceil(x0 + hx)));
        const long j0 = std::max(0L, long(std::floor(y0 - hy))),
                   j1 = std::min(ny - 1, long(std::ceil(y0 + hy)));
        double s = 0.0, sx = 0.0, sy = 0.0, sxx = 0.0, syy = 0.0, sxy = 0.0;
        for (long j = j0; j <= j1; ++j) {
            const double dy = double(j) - y0;
            for (long i = i0; i <= i1; ++i) {
                if (mask && (*mask)(j, i)) continue;
                const double v = image(j, i);
                if (!std::isfinite(v)) continue;
                const double dx = double(i) - x0;
                const double rho2 = i11 * dx * dx + 2.0 * i12 * dx * dy + i22 * dy * dy;
                if (rho2 > 25.0) continue;
                const double wv = std::exp(-0.5 * rho2) * v;
                s += wv;
                sx += wv * dx;
                sy += wv * dy;
                sxx += wv * dx * dx;
                syy += wv * dy * dy;
                sxy += wv * dx * dy;
            }
        }
        if (!(s > 0.0)) return fail("no positive light under the weight");
        const double ddx = sx / s, ddy = sy / s;
        const double c11 = sxx / s - ddx * ddx, c22 = syy / s - ddy * ddy,
                     c12 = sxy / s - ddx * ddy;
        double n11 = 2.0 * c11, n22 = 2.0 * c22, n12 = 2.0 * c12;
        if (!(n11 > 0.0 && n22 > 0.0 && n11 * n22 - n12 * n12 > 0.0))
            return fail("the weighted moments are not positive definite");
        // No more than a factor 4 in size a pass (noise can throw a first pass far).
        const double t_old = m11 + m22, t_new = n11 + n22;
        if (t_new > 4.0 * t_old || t_new < 0.25 * t_old) {
            const double f = std::clamp(t_new, 0.25 * t_old, 4.0 * t_old) / t_new;
            n11 *= f, n22 *= f, n12 *= f;
        }
        const double step = std::hypot(2.0 * ddx, 2.0 * ddy);
        const double change =
            (std::abs(n11 - m11) + std::abs(n22 - m22) + 2.0 * std::abs(n12 - m12)) / t_old;
        x0 += 2.0 * ddx;
        y0 += 2.0 * ddy;
        m11 = n11, m22 = n22, m12 = n12;
        if (!(x0 >= 0.0 && x0 <= double(nx - 1) && y0 >= 0.0 && y0 <= double(ny - 1)))
            return fail("the centre left the image");
        if (step < 1e-7 && change < 1e-8) {
            AdaptiveMoments a;
            a.x = x0;
            a.y = y0;
            a.m11 = m11;
            a.m22 = m22;
            a.m12 = m12;
            a.iterations = pass;
            return a;
        }
    }
    return fail("no convergence in 200 passes");
}

std::optional<ShearEstimate> linear_shear_estimate(const AdaptiveMoments& object,
                                                   const AdaptiveMoments& psf) {
    const double q11 = object.m11 - psf.m11, q22 = object.m22 - psf.m22, q12 = object.m12 - psf.m12;
    const double t = q11 + q22, det = q11 * q22 - q12 * q12;
    if (!(t > 0.0 && det > 0.0)) return std::nullopt;
    const Complex chi((q11 - q22) / t, 2.0 * q12 / t);
    ShearEstimate e;
    e.epsilon = chi / (1.0 + std::sqrt(std::max(0.0, 1.0 - std::norm(chi))));
    e.resolution = 1.0 - psf.trace() / object.trace();
    return e;
}

AdaptiveMoments psf_adaptive_moments(const ShapeletModel& psf) {
    // A stamp of ±(reach) pixels, the model on its central pixel.
    const double reach = psf.beta_pix * (std::sqrt(2.0 * psf.n_max + 1.0) + 6.0);
    const int half = std::clamp(int(std::ceil(reach)), 8, 2000);
    const int n = 2 * half + 1;
    ShapeletModel centred = psf;
    centred.x = double(half + 1);
    centred.y = double(half + 1);
    const ImageArray stamp = render_stamp(centred, n, n);
    std::string why;
    const auto m = adaptive_moments(stamp, nullptr, double(half), double(half),
                                    std::max(1.0, psf.beta_pix), &why);
    if (!m) throw Error("the PSF's adaptive moments: " + why);
    return *m;
}

}  // namespace shapesim
