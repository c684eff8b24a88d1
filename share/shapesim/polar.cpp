#include "shapesim/polar.hpp"

#include "shapesim/error.hpp"

#include <cmath>
#include <map>
#include <memory>
#include <mutex>

namespace shapesim {

namespace {
constexpr double kInvSqrtPi = 0.56418958354775628695;  // 1/√π
constexpr double kRescale = 1e100;
}  // namespace

void polar_basis(double dx, double dy, double beta_pix, int n_max, Complex* out) {
    const double t = (dx * dx + dy * dy) / (beta_pix * beta_pix);
    const double theta = std::atan2(dy, dx);
    const double prefactor = kInvSqrtPi / beta_pix;
    const double log_t = t > 0.0 ? std::log(t) : 0.0;
    double log_factorial = 0.0;  // log m!, summed here: std::lgamma writes a global (races)
    for (int m = 0; m <= n_max; ++m) {
        if (m > 0) log_factorial += std::log(double(m));
        // g_0 = t^{m/2} e^{-t/2} / √(m!) in logs; the recurrence runs on g / exp(log_scale).
        double log_scale;
        if (t > 0.0)
            log_scale = 0.5 * m * log_t - 0.5 * t - 0.5 * log_factorial;
        else
            log_scale = (m == 0) ? 0.0 : -HUGE_VAL;
        double factor = std::exp(log_scale);
        const Complex phase = std::polar(1.0, m * theta);
        double g_prev = 0.0, g = 1.0;
        for (int q = 0; m + 2 * q <= n_max; ++q) {
            if (q > 0) {
                const int k = q - 1;  // step from g_k to g_{k+1}
                const double next =
                    (2.0 * k + m + 1.0 - t) / std::sqrt((k + 1.0) * (k + m + 1.0)) * g -
                    std::sqrt(k * (k + m) / ((k + 1.0) * (k + m + 1.0))) * g_prev;
                g_prev = g;
                g = next;
                if (std::abs(g) > kRescale) {
                    g /= kRescale;
                    g_prev /= kRescale;
                    log_scale += std::log(kRescale);
                    factor = std::exp(log_scale);
                }
            }
            const double sign = (q % 2 == 0) ? 1.0 : -1.0;
            out[polar_index(m + 2 * q, m)] = (sign * prefactor * g * factor) * phase;
        }
    }
}

double evaluate(const ShapeletModel& model, double x, double y) {
    std::vector<Complex> chi(polar_count(model.n_max));
    polar_basis(x - model.x, y - model.y, model.beta_pix, model.n_max, chi.data());
    double value = 0.0;
    int k = 0;
    for (const auto& [n, m] : polar_indices(model.n_max)) {
        (void)n;
        const double term = (model.coeffs[k] * chi[k]).real();
        value += (m == 0) ? term : 2.0 * term;
        ++k;
    }
    return value;
}

namespace {
// T^{(n)} from T^{(n−1)} by the ladder operators of the 2D oscillator. χ_{n,m} is the circular
// state |n_r, n_l⟩, n_r = (n+m)/2, n_l = (n−m)/2, built by a_r† = (a_x† + i a_y†)/√2 and
// a_l† = (a_x† − i a_y†)/√2 (phases included: checked against the paper's formula by
// quadrature in tests/unit/polar_test.cpp). With a_x†|n1,n2⟩ = √(n1+1)|n1+1,n2⟩:
//   √n_r |n_r, n_l⟩ = (a_x† + i a_y†)/√2 |n_r−1, n_l⟩,
//   √n_l |n_r, n_l⟩ = (a_x† − i a_y†)/√2 |n_r, n_l−1⟩.
// The step is taken along the larger of n_r, n_l: its 1/√(2 max(n_r, n_l)) keeps each step's
// error gain ≤ 1 (stepping along a small n_r amplifies rounding ~√(n/n_r) per order).
Eigen::MatrixXcd compute_polar_cartesian(int n, const Eigen::MatrixXcd* previous) {
    Eigen::MatrixXcd t = Eigen::MatrixXcd::Zero(n + 1, n + 1);
    if (n == 0) {
        t(0, 0) = 1.0;
        return t;
    }
    for (int n_r = 0; n_r <= n; ++n_r) {
        const int n_l = n - n_r;
        // The parent state at order n−1 (its row index is its n_r) and the ladder used.
        const bool right = n_r >= n_l;
        const int parent_row = right ? n_r - 1 : n_r;
        const Complex phase = right ? Complex(0.0, 1.0) : Complex(0.0, -1.0);
        const double norm = 1.0 / std::sqrt(2.0 * (right ? n_r : n_l));
        for (int n1 = 0; n1 <= n; ++n1) {
            const int n2 = n - n1;
            Complex v = 0.0;
            if (n1 > 0) v += std::sqrt(double(n1)) * (*previous)(parent_row, n1 - 1);
            if (n2 > 0) v += phase * std::sqrt(double(n2)) * (*previous)(parent_row, n1);
            t(n_r, n1) = norm * v;
        }
    }
    // One Newton–Schulz step towards the nearest unitary matrix, T ← T (3 − T†T)/2: removes
    // the rounding error the step added to T's unitarity, so it cannot compound over orders.
    const Eigen::MatrixXcd gram = t.adjoint() * t;
    t = t * (3.0 * Eigen::MatrixXcd::Identity(n + 1, n + 1) - gram) * 0.5;
    return t;
}

template <class Value, class Make>
const Value& cached(std::map<int, std::unique_ptr<Value>>& cache, std::mutex& mutex, int key,
                    Make make) {
    std::lock_guard<std::mutex> lock(mutex);
    auto& slot = cache[key];
    if (!slot) slot = std::make_unique<Value>(make(key));
    return *slot;
}

// Block of order n: real parameters (m ≥ 0: Re a, then Im a for m > 0) → b(n1, n − n1).
Eigen::MatrixXd compute_real_to_cartesian_block(int n) {
    const Eigen::MatrixXcd& t = polar_cartesian_matrix(n);
    Eigen::MatrixXd r = Eigen::MatrixXd::Zero(n + 1, n + 1);
    int column = 0;
    for (int m = n % 2; m <= n; m += 2) {
        const int row_m = (n + m) / 2;
        for (int n1 = 0; n1 <= n; ++n1) {
            if (m == 0) {
                r(n1, column) = t(row_m, n1).real();
            } else {  // a χ_m + conj(a χ_m) = 2 Re(a) Re χ_m − 2 Im(a) Im χ_m
                r(n1, column) = 2.0 * t(row_m, n1).real();
                r(n1, column + 1) = -2.0 * t(row_m, n1).imag();
            }
        }
        column += (m == 0) ? 1 : 2;
    }
    return r;
}

// Its inverse: a_m = Σ_{n1} b(n1) conj T_{m,n1} (T unitary).
Eigen::MatrixXd compute_cartesian_to_real_block(int n) {
    const Eigen::MatrixXcd& t = polar_cartesian_matrix(n);
    Eigen::MatrixXd r = Eigen::MatrixXd::Zero(n + 1, n + 1);
    int row = 0;
    for (int m = n % 2; m <= n; m += 2) {
        const int row_m = (n + m) / 2;
        for (int n1 = 0; n1 <= n; ++n1) {
            r(row, n1) = t(row_m, n1).real();
            if (m > 0) r(row + 1, n1) = -t(row_m, n1).imag();
        }
        row += (m == 0) ? 1 : 2;
    }
    return r;
}
}  // namespace

const Eigen::MatrixXcd& polar_cartesian_matrix(int n) {
    require(n >= 0, "polar_cartesian_matrix: negative order");
    static std::mutex mutex;
    static std::map<int, std::unique_ptr<Eigen::MatrixXcd>> cache;
    // The parent order first (its own lock), so the lock is never held across the recursion.
    const Eigen::MatrixXcd* previous = n > 0 ? &polar_cartesian_matrix(n - 1) : nullptr;
    return cached(cache, mutex, n, [previous](int order) {
        return compute_polar_cartesian(order, previous);
    });
}

const Eigen::MatrixXd& change_basis_block(BasisChange direction, int n) {
    require(n >= 0, "change_basis_block: negative order");
    static std::mutex mutex;
    static std::map<int, std::unique_ptr<Eigen::MatrixXd>> to_cartesian_cache, to_real_cache;
    if (direction == BasisChange::real_to_cartesian)
        return cached(to_cartesian_cache, mutex, n, compute_real_to_cartesian_block);
    return cached(to_real_cache, mutex, n, compute_cartesian_to_real_block);
}

Eigen::MatrixXd change_basis_rows(BasisChange direction, const Eigen::MatrixXd& x, int n_max) {
    require(x.rows() == real_count(n_max), "change_basis_rows: size does not match n_max");
    Eigen::MatrixXd out(x.rows(), x.cols());
    for (int n = 0; n <= n_max; ++n) {
        const int offset = n * (n + 1) / 2;
        out.middleRows(offset, n + 1).noalias() =
            change_basis_block(direction, n) * x.middleRows(offset, n + 1);
    }
    return out;
}

Eigen::MatrixXd change_basis_columns(BasisChange direction, const Eigen::MatrixXd& x, int n_max) {
    require(x.cols() == real_count(n_max), "change_basis_columns: size does not match n_max");
    Eigen::MatrixXd out(x.rows(), x.cols());
    for (int n = 0; n <= n_max; ++n) {
        const int offset = n * (n + 1) / 2;
        out.middleCols(offset, n + 1).noalias() =
            x.middleCols(offset, n + 1) * change_basis_block(direction, n);
    }
    return out;
}

Eigen::VectorXd pack_cartesian(const Eigen::MatrixXd& b, int n_max) {
    Eigen::VectorXd packed(real_count(n_max));
    for (int n = 0; n <= n_max; ++n)
        for (int n1 = 0; n1 <= n; ++n1) packed(cartesian_index(n1, n - n1)) = b(n1, n - n1);
    return packed;
}

Eigen::MatrixXd unpack_cartesian(const Eigen::VectorXd& packed, int n_max) {
    Eigen::MatrixXd b = Eigen::MatrixXd::Zero(n_max + 1, n_max + 1);
    for (int n = 0; n <= n_max; ++n)
        for (int n1 = 0; n1 <= n; ++n1) b(n1, n - n1) = packed(cartesian_index(n1, n - n1));
    return b;
}

CartesianModel to_cartesian(const ShapeletModel& model) {
    CartesianModel out(model.x, model.y, model.beta_pix, model.n_max);
    out.b = unpack_cartesian(
        change_basis_rows(BasisChange::real_to_cartesian, real_parameters(model), model.n_max),
        model.n_max);
    return out;
}

ShapeletModel to_polar(const CartesianModel& model) {
    ShapeletModel out(model.x, model.y, model.beta_pix, model.n_max);
    set_real_parameters(out, change_basis_rows(BasisChange::cartesian_to_real,
                                               pack_cartesian(model.b, model.n_max), model.n_max));
    return out;
}

}  // namespace shapesim
