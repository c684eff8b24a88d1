#include "shapesim/model.hpp"

#include "shapesim/error.hpp"

#include <cmath>
#include <string>

namespace shapesim {

std::vector<PolarIndex> polar_indices(int n_max) {
    std::vector<PolarIndex> out;
    out.reserve(polar_count(n_max));
    for (int n = 0; n <= n_max; ++n)
        for (int m = n % 2; m <= n; m += 2) out.push_back({n, m});
    return out;
}

void ShapeletModel::validate() const {
    if (n_max < 0) throw Error("n_max must be >= 0, got " + std::to_string(n_max), {}, 0, "n_max");
    if (!(beta_pix > 0.0) || !std::isfinite(beta_pix))
        throw Error("must be finite and > 0, got " + std::to_string(beta_pix), {}, 0, "beta");
    if (!std::isfinite(x) || !std::isfinite(y)) throw Error("centre is not finite", {}, 0, "x");
    if (int(coeffs.size()) != polar_count(n_max))
        throw Error("expected " + std::to_string(polar_count(n_max)) + " coefficients for n_max " +
                        std::to_string(n_max) + ", got " + std::to_string(coeffs.size()),
                    {}, 0, "coeffs");
    int k = 0;
    for (const auto& [n, m] : polar_indices(n_max)) {
        const Complex c = coeffs[k++];
        if (!std::isfinite(c.real()) || !std::isfinite(c.imag()))
            throw Error("a_{" + std::to_string(n) + "," + std::to_string(m) + "} is not finite",
                        {}, 0, "coeffs");
        if (m == 0 && c.imag() != 0.0)
            throw Error("a_{" + std::to_string(n) + ",0} must be real", {}, 0, "coeffs");
    }
}

Eigen::VectorXd real_parameters(const ShapeletModel& model) {
    Eigen::VectorXd p(real_count(model.n_max));
    int j = 0, k = 0;
    for (const auto& [n, m] : polar_indices(model.n_max)) {
        (void)n;
        p(j++) = model.coeffs[k].real();
        if (m > 0) p(j++) = model.coeffs[k].imag();
        ++k;
    }
    return p;
}

void set_real_parameters(ShapeletModel& model, const Eigen::VectorXd& params) {
    require(params.size() == real_count(model.n_max), "set_real_parameters: wrong size");
    model.coeffs.assign(polar_count(model.n_max), Complex(0.0, 0.0));
    int j = 0, k = 0;
    for (const auto& [n, m] : polar_indices(model.n_max)) {
        (void)n;
        if (m == 0) {
            model.coeffs[k] = Complex(params(j), 0.0);
            j += 1;
        } else {
            model.coeffs[k] = Complex(params(j), params(j + 1));
            j += 2;
        }
        ++k;
    }
}

ShapeletModel with_n_max(const ShapeletModel& model, int n_max) {
    ShapeletModel out(model.x, model.y, model.beta_pix, n_max);
    const int common = std::min(polar_count(n_max), polar_count(model.n_max));
    for (int k = 0; k < common; ++k) out.coeffs[k] = model.coeffs[k];
    return out;
}

}  // namespace shapesim
