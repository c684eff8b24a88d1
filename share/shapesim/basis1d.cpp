#include "shapesim/basis1d.hpp"

#include "shapesim/error.hpp"
#include "shapesim/lane_math.hpp"

#include <cmath>
#include <cstring>
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
constexpr double kPhi0Scale = 0.75112554446494248286 * 1.2533141373155002512;  // π^{-1/4} √(π/2)
constexpr double kInvSqrt2 = 0.70710678118654752440;

// The tail of φ_0 beyond |u|, up to kPhi0Scale: erfc(|u|/√2).
double phi0_tail(double u) { return std::erfc(std::abs(u) * kInvSqrt2); }

// ∫_{u_a}^{u_b} φ_0 du for a span wholly on one side of 0 (u_a ≥ 0 or u_b ≤ 0), from its
// edges' tails: a difference of erfc, so that a far-out pixel keeps relative accuracy.
double integral_phi0_one_side(double u_a, double tail_a, double tail_b) {
    return u_a >= 0 ? kPhi0Scale * (tail_a - tail_b) : kPhi0Scale * (tail_b - tail_a);
}

// ∫_{u_a}^{u_b} φ_0 du.
double integral_phi0(double u_a, double u_b) {
    if (u_a >= 0 || u_b <= 0) return integral_phi0_one_side(u_a, phi0_tail(u_a), phi0_tail(u_b));
    return kPhi0Scale * (std::erf(u_b * kInvSqrt2) - std::erf(u_a * kInvSqrt2));
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

namespace {

// ∫φ_0 over pixel i of pixel_basis_1d (edges first_offset + i ∓ ½, over β) as integral_phi0
// gives it, with each edge's tail computed once: the next pixel takes a pixel's right-edge
// tail as its left one when its u_a is the same double (almost always; the erfc were most of a
// low-order stamp's basis). Call for i = 0, 1, 2, … in turn.
class PixelPhi0 {
public:
    PixelPhi0(double beta_pix, double first_offset) : beta_(beta_pix), first_(first_offset) {}
    double operator()(int i) {
        const double u_a = (first_ + i - 0.5) / beta_, u_b = (first_ + i + 0.5) / beta_;
        if (!(u_a >= 0 || u_b <= 0)) return integral_phi0(u_a, u_b);
        const double tail_a = u_a == shared_u_ ? shared_tail_ : phi0_tail(u_a);
        shared_u_ = u_b;
        shared_tail_ = phi0_tail(u_b);
        return integral_phi0_one_side(u_a, tail_a, shared_tail_);
    }

private:
    double beta_, first_;
    double shared_u_ = std::numeric_limits<double>::quiet_NaN(), shared_tail_ = 0.0;
};

#ifdef SHAPESIM_LANES_X86
using lane::Doubles4;

// hermite_functions at four points in lanes (points[j] and their e^{−u²/2}), at[k · stride + j]
// = φ_k(u_j): the same operations in the same order, so the same bits. False when a lane would
// need hermite_functions' rescaling (|ψ| past 1e100: orders in the hundreds); `at` is then junk.
// (Lanes are not passed by value: clang refuses that from AVX2 code to code without it.)
SHAPESIM_LANES bool hermite_functions4(const double* points, const double* factors, int n_max,
                                       double* at, long stride) {
    Doubles4 u, factor;
    std::memcpy(&u, points, sizeof u);
    std::memcpy(&factor, factors, sizeof factor);
    Doubles4 psi_prev = Doubles4{}, psi = Doubles4{} + kPiQuarterInv;
    Doubles4 value = psi * factor;
    std::memcpy(at, &value, sizeof value);
    const Recurrence& c = recurrence();
    lane::Mask4 big = lane::Mask4{};
    for (int n = 0; n < n_max; ++n) {
        const Doubles4 psi_next = c.raise(n) * u * psi - c.lower(n) * psi_prev;
        psi_prev = psi;
        psi = psi_next;
        big |= lane::abs(psi) > kRescale;
        value = psi * factor;
        std::memcpy(at + (n + 1) * stride, &value, sizeof value);
    }
    return (big[0] | big[1] | big[2] | big[3]) == 0;
}

// pixel_basis_1d four edges, then four pixels, at a time: the edge values into `at`, a
// row-major (n_max+1) × (npix+1) scratch (at(k, e): the lanes' values side by side), then
// integrals_from_edges in lanes; the rare edges that need rescaling and the last pixels one
// at a time. Every value is the scalar code's, bit for bit.
__attribute__((target("avx2"))) void pixel_basis_avx2(int n_max, double beta_pix,
                                                     double first_offset, int npix,
                                                     Eigen::Ref<Eigen::MatrixXd>& out, double* at) {
    const long stride = npix + 1;
    std::vector<double> a(std::size_t(n_max) + 1), b(std::size_t(n_max) + 1);
    for (int e = 0; e <= npix; e += 4) {
        if (e + 4 <= npix + 1) {
            double u[4], factor[4];
            for (int j = 0; j < 4; ++j) {
                u[j] = (first_offset + (e + j) - 0.5) / beta_pix;
                factor[j] = std::exp(-0.5 * u[j] * u[j]);  // hermite_functions' own
            }
            if (hermite_functions4(u, factor, n_max, at + e, stride)) continue;
        }
        for (int f = e; f < std::min(e + 4, npix + 1); ++f) {
            hermite_functions((first_offset + f - 0.5) / beta_pix, n_max, a.data());
            for (int k = 0; k <= n_max; ++k) at[k * stride + f] = a[std::size_t(k)];
        }
    }
    const double norm = std::sqrt(beta_pix);
    const Recurrence& c = recurrence();
    PixelPhi0 phi0(beta_pix, first_offset);
    int i = 0;
    for (; i + 4 <= npix; i += 4) {
        Doubles4 before, last, left, right, scaled;  // I_{k−1}, I_k; edge values
        for (int j = 0; j < 4; ++j) last[j] = phi0(i + j);
        // (No lambda takes a lane: it would not be an AVX2 function.)
#define SHAPESIM_STORE(k)                                              \
    scaled = last * norm;                                              \
    for (int j = 0; j < 4; ++j) out((k), i + j) = scaled[j];
        SHAPESIM_STORE(0)
        if (n_max < 1) continue;
        std::memcpy(&left, at + i, sizeof left);
        std::memcpy(&right, at + i + 1, sizeof right);
        before = last;
        last = -std::sqrt(2.0) * (right - left);
        SHAPESIM_STORE(1)
        for (int k = 1; k < n_max; ++k) {
            std::memcpy(&left, at + k * stride + i, sizeof left);
            std::memcpy(&right, at + k * stride + i + 1, sizeof right);
            const Doubles4 next = c.lower(k) * before - c.raise(k) * (right - left);
            before = last;
            last = next;
            SHAPESIM_STORE(k + 1)
        }
#undef SHAPESIM_STORE
    }
    for (; i < npix; ++i) {
        for (int k = 0; k <= n_max; ++k) {
            a[std::size_t(k)] = at[k * stride + i];
            b[std::size_t(k)] = at[k * stride + i + 1];
        }
        integrals_from_edges(phi0(i), a.data(), b.data(), n_max, out.col(i).data());
        out.col(i) *= norm;
    }
}
#endif

}  // namespace

void pixel_basis_1d(int n_max, double beta_pix, double first_offset, int npix,
                    Eigen::Ref<Eigen::MatrixXd> out, Eigen::Ref<Eigen::MatrixXd> edges) {
    require(n_max >= 0 && beta_pix > 0 && npix >= 0, "pixel_basis_1d: bad arguments");
    require(out.rows() == n_max + 1 && out.cols() == npix && edges.rows() == n_max + 1 &&
                edges.cols() == npix + 1,
            "pixel_basis_1d: wrong buffer sizes");
    if (npix == 0) return;
#ifdef SHAPESIM_LANES_X86
    if (lane::have_avx2())
        return pixel_basis_avx2(n_max, beta_pix, first_offset, npix, out, edges.data());
#endif
    // φ at the npix+1 pixel edges, each computed once and shared by its two pixels.
    for (int e = 0; e <= npix; ++e)
        hermite_functions((first_offset + e - 0.5) / beta_pix, n_max, edges.col(e).data());
    const double norm = std::sqrt(beta_pix);  // ∫ B_n dx = β^{1/2} I_n
    PixelPhi0 phi0(beta_pix, first_offset);
    for (int i = 0; i < npix; ++i) {
        integrals_from_edges(phi0(i), edges.col(i).data(), edges.col(i + 1).data(), n_max,
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
    for (int n = 1; n + 1 < width; n += 2)
        m(0, n + 1) = std::sqrt(double(n) / (n + 1)) * m(0, n - 1);
    for (int p = 1; p <= p_max; ++p)
        for (int n = 0; n + 1 < width; ++n)
            m(p, n) = std::sqrt((n + 1) / 2.0) * m(p - 1, n + 1) +
                      (n > 0 ? std::sqrt(n / 2.0) * m(p - 1, n - 1) : 0.0);
    return m.leftCols(n_max + 1);
}

}  // namespace shapesim
