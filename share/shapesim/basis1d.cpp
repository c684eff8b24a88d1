#include "shapesim/basis1d.hpp"

#include "shapesim/error.hpp"

#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <mutex>

namespace shapesim {

namespace {
constexpr double kPiQuarterInv = 0.75112554446494248286;  // π^{-1/4}
constexpr double kRescale = 1e100;                          // keeps ψ_n far from overflow
const double kLogRescale = std::log(kRescale);

// The recurrences' coefficients √(2/(n+1)) and √(n/(n+1)), tabulated: the same correctly
// rounded numbers as computed in place, without two square roots and two divisions a step
// (they were most of the time of a stamp's basis).
struct Recurrence {
    static constexpr int size = 1024;
    double up[size], down[size];
    Recurrence() {
        for (int n = 0; n < size; ++n) {
            up[n] = std::sqrt(2.0 / (n + 1));
            down[n] = std::sqrt(double(n) / (n + 1));
        }
    }
    double raise(int n) const { return n < size ? up[n] : std::sqrt(2.0 / (n + 1)); }
    double lower(int n) const { return n < size ? down[n] : std::sqrt(double(n) / (n + 1)); }
};
const Recurrence& recurrence() {
    static const Recurrence table;
    return table;
}
}  // namespace

void hermite_functions(double u, int n_max, double* out) {
    if (n_max < 0) return;
    // Run the recurrence on ψ_n = φ_n e^{u²/2} · e^{-log_scale'}: the Gaussian factor is applied
    // at the end, so φ_0 underflowing at large |u| does not zero out the higher orders.
    double log_scale = -0.5 * u * u;
    double factor = std::exp(log_scale);
    double psi_prev = 0.0, psi = kPiQuarterInv;
    out[0] = psi * factor;
    const Recurrence& c = recurrence();
    for (int n = 0; n < n_max; ++n) {
        const double psi_next = c.raise(n) * u * psi - c.lower(n) * psi_prev;
        psi_prev = psi;
        psi = psi_next;
        if (std::abs(psi) > kRescale) {
            psi /= kRescale;
            psi_prev /= kRescale;
            log_scale += kLogRescale;
            factor = std::exp(log_scale);
        }
        out[n + 1] = psi * factor;
    }
}

namespace {
// ∫_{u_a}^{u_b} φ_0 du, using erfc in the tails so that a far-out pixel keeps relative accuracy.
double integral_phi0(double u_a, double u_b) {
    constexpr double c = 0.75112554446494248286 * 1.2533141373155002512;  // π^{-1/4} √(π/2)
    const double s = 0.70710678118654752440;                            // 1/√2
    if (u_a >= 0) return c * (std::erfc(u_a * s) - std::erfc(u_b * s));
    if (u_b <= 0) return c * (std::erfc(-u_b * s) - std::erfc(-u_a * s));
    return c * (std::erf(u_b * s) - std::erf(u_a * s));
}

// I_n from the edge values: phi_a, phi_b hold φ_0..φ_{n_max} at u_a and u_b.
void integrals_from_edges(double i0, const double* phi_a, const double* phi_b, int n_max,
                          double* out) {
    out[0] = i0;
    if (n_max >= 1) out[1] = -std::sqrt(2.0) * (phi_b[0] - phi_a[0]);
    const Recurrence& c = recurrence();
    for (int n = 1; n < n_max; ++n)
        out[n + 1] = c.lower(n) * out[n - 1] - c.raise(n) * (phi_b[n] - phi_a[n]);
}
}  // namespace

void hermite_integrals(double u_a, double u_b, int n_max, double* out) {
    if (n_max < 0) return;
    std::vector<double> phi_a(n_max + 1), phi_b(n_max + 1);
    hermite_functions(u_a, n_max, phi_a.data());
    hermite_functions(u_b, n_max, phi_b.data());
    integrals_from_edges(integral_phi0(u_a, u_b), phi_a.data(), phi_b.data(), n_max, out);
}

Eigen::MatrixXd sampled_basis_1d(int n_max, double beta_pix, double first_offset, int npix) {
    require(n_max >= 0 && beta_pix > 0 && npix >= 0, "sampled_basis_1d: bad arguments");
    Eigen::MatrixXd out(n_max + 1, npix);
    const double norm = 1.0 / std::sqrt(beta_pix);
    for (int i = 0; i < npix; ++i) {
        hermite_functions((first_offset + i) / beta_pix, n_max, out.col(i).data());
        out.col(i) *= norm;
    }
    return out;
}

void pixel_basis_1d(int n_max, double beta_pix, double first_offset, int npix,
                    Eigen::Ref<Eigen::MatrixXd> out, Eigen::Ref<Eigen::MatrixXd> edges) {
    require(n_max >= 0 && beta_pix > 0 && npix >= 0, "pixel_basis_1d: bad arguments");
    require(out.rows() == n_max + 1 && out.cols() == npix && edges.rows() == n_max + 1 &&
                edges.cols() == npix + 1,
            "pixel_basis_1d: wrong buffer sizes");
    if (npix == 0) return;
    // φ at the npix+1 pixel edges, each computed once and shared by its two pixels.
    for (int e = 0; e <= npix; ++e)
        hermite_functions((first_offset + e - 0.5) / beta_pix, n_max, edges.col(e).data());
    const double norm = std::sqrt(beta_pix);  // ∫ B_n dx = β^{1/2} I_n
    // ∫φ_0 as integral_phi0 gives it, with each edge's erfc computed once: a pixel wholly on
    // one side of the centre takes erfc(|u| / √2) at its two edges, the next pixel the same
    // value at its left edge when its u_a is the same double (almost always; the erfc were
    // most of a low-order stamp's basis).
    constexpr double c = 0.75112554446494248286 * 1.2533141373155002512;  // as integral_phi0
    const double s = 0.70710678118654752440;
    double shared_u = std::numeric_limits<double>::quiet_NaN(), shared_tail = 0.0;
    for (int i = 0; i < npix; ++i) {
        const double u_a = (first_offset + i - 0.5) / beta_pix;
        const double u_b = (first_offset + i + 0.5) / beta_pix;
        double i0;
        if (u_a >= 0 || u_b <= 0) {
            const double tail_a = u_a == shared_u ? shared_tail : std::erfc(std::abs(u_a) * s);
            const double tail_b = std::erfc(std::abs(u_b) * s);
            i0 = u_a >= 0 ? c * (tail_a - tail_b) : c * (tail_b - tail_a);
            shared_u = u_b;
            shared_tail = tail_b;
        } else {
            i0 = integral_phi0(u_a, u_b);
        }
        integrals_from_edges(i0, edges.col(i).data(), edges.col(i + 1).data(), n_max,
                             out.col(i).data());
        out.col(i) *= norm;
    }
}

Eigen::MatrixXd pixel_basis_1d(int n_max, double beta_pix, double first_offset, int npix) {
    require(n_max >= 0 && npix >= 0, "pixel_basis_1d: bad arguments");
    Eigen::MatrixXd out(n_max + 1, npix), edges(n_max + 1, npix + 1);
    pixel_basis_1d(n_max, beta_pix, first_offset, npix, out, edges);
    return out;
}

namespace {
GaussHermite compute_gauss_hermite(int k) {
    // Golub–Welsch: nodes are eigenvalues of the Jacobi matrix of the physicists' Hermite
    // polynomials (off-diagonal √(j/2)); then Newton on φ_K using φ_K' = √(2K) φ_{K−1} − u φ_K.
    Eigen::MatrixXd jacobi = Eigen::MatrixXd::Zero(k, k);
    for (int j = 1; j < k; ++j) jacobi(j, j - 1) = jacobi(j - 1, j) = std::sqrt(j / 2.0);
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(jacobi, Eigen::EigenvaluesOnly);
    GaussHermite rule;
    rule.nodes.resize(k);
    rule.weights.resize(k);
    std::vector<double> phi(k + 1);
    for (int i = 0; i < k; ++i) {
        double u = solver.eigenvalues()(i);
        for (int iter = 0; iter < 3; ++iter) {
            hermite_functions(u, k, phi.data());
            const double derivative = std::sqrt(2.0 * k) * phi[k - 1] - u * phi[k];
            if (derivative == 0.0) break;
            u -= phi[k] / derivative;
        }
        hermite_functions(u, k - 1, phi.data());
        double sum = 0.0;
        for (int j = 0; j < k; ++j) sum += phi[j] * phi[j];
        rule.nodes[i] = u;
        rule.weights[i] = 1.0 / sum;
    }
    // Enforce exact symmetry of the rule (nodes ±u, equal weights).
    for (int i = 0; i < k / 2; ++i) {
        const double u = 0.5 * (rule.nodes[k - 1 - i] - rule.nodes[i]);
        const double w = 0.5 * (rule.weights[k - 1 - i] + rule.weights[i]);
        rule.nodes[i] = -u;
        rule.nodes[k - 1 - i] = u;
        rule.weights[i] = rule.weights[k - 1 - i] = w;
    }
    if (k % 2 == 1) rule.nodes[k / 2] = 0.0;
    return rule;
}
}  // namespace

const GaussHermite& gauss_hermite(int k) {
    require(k >= 1, "gauss_hermite: need at least one node");
    static std::mutex mutex;
    static std::map<int, std::unique_ptr<GaussHermite>> cache;
    std::lock_guard<std::mutex> lock(mutex);
    auto& slot = cache[k];
    if (!slot) slot = std::make_unique<GaussHermite>(compute_gauss_hermite(k));
    return *slot;
}

Eigen::MatrixXd hermite_moments(int p_max, int n_max) {
    require(p_max >= 0 && n_max >= 0, "hermite_moments: bad arguments");
    // Row p needs row p−1 up to n_max+1, so build wider and crop.
    const int width = n_max + p_max + 2;
    Eigen::MatrixXd m = Eigen::MatrixXd::Zero(p_max + 1, width);
    m(0, 0) = std::sqrt(2.0) / kPiQuarterInv;  // ∫ φ_0 = π^{-1/4} √(2π) = √2 π^{1/4}
    for (int n = 1; n + 1 < width; n += 2) m(0, n + 1) = std::sqrt(double(n) / (n + 1)) * m(0, n - 1);
    for (int p = 1; p <= p_max; ++p)
        for (int n = 0; n + 1 < width; ++n)
            m(p, n) = std::sqrt((n + 1) / 2.0) * m(p - 1, n + 1) +
                      (n > 0 ? std::sqrt(n / 2.0) * m(p - 1, n - 1) : 0.0);
    return m.leftCols(n_max + 1);
}

}  // namespace shapesim
