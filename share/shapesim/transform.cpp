#include "shapesim/transform.hpp"

#include "shapesim/basis1d.hpp"
#include "shapesim/error.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/polar.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace shapesim {

namespace {

void require_sized(const ShapeletModel& model, const char* who) {
    require(model.n_max >= 0 && int(model.coeffs.size()) == polar_count(model.n_max),
            std::string(who) + ": coefficient count does not match n_max");
    require(model.beta_pix > 0.0 && std::isfinite(model.beta_pix),
            std::string(who) + ": beta must be finite and > 0");
}

/// a_{n,m} → a_{n,m} e^{−imρ} in place.
void apply_phases(ShapeletModel& model, double rho) {
    int k = 0;
    for (const auto& [n, m] : polar_indices(model.n_max)) {
        (void)n;
        if (m > 0) model.coeffs[k] *= std::polar(1.0, -m * rho);
        ++k;
    }
}

}  // namespace

ShapeletModel rotate(const ShapeletModel& model, double rho) {
    require_sized(model, "rotate");
    ShapeletModel out = model;
    apply_phases(out, rho);
    return out;
}

ShapeletModel rotate_about(const ShapeletModel& model, double rho, double x0, double y0) {
    ShapeletModel out = rotate(model, rho);
    const double c = std::cos(rho), s = std::sin(rho);
    const double dx = model.x - x0, dy = model.y - y0;
    out.x = x0 + c * dx - s * dy;
    out.y = y0 + s * dx + c * dy;
    return out;
}

ShapeletModel reflect_x(const ShapeletModel& model) {
    require_sized(model, "reflect_x");
    ShapeletModel out = model;
    for (Complex& a : out.coeffs) a = std::conj(a);
    return out;
}

ShapeletModel reflect(const ShapeletModel& model, double psi) {
    // S_ψ = R(ψ) diag(1, −1) R(−ψ): rotate by −ψ, mirror in x, rotate by ψ.
    ShapeletModel out = reflect_x(model);
    apply_phases(out, 2.0 * psi);
    return out;
}

ShapeletModel dilate(const ShapeletModel& model, double scale, bool conserve_flux) {
    require_sized(model, "dilate");
    require(scale > 0.0 && std::isfinite(scale), "dilate: scale must be finite and > 0");
    ShapeletModel out = model;
    out.beta_pix = model.beta_pix * scale;
    const double factor = conserve_flux ? 1.0 / scale : scale;
    for (Complex& a : out.coeffs) a *= factor;
    return out;
}

// ---------------------------------------------------------------------------------------------
// Re-projection.

namespace {

/// b(n1, n2) of a polar model, order by order with the cached unitary T^{(n)} (polar.hpp):
/// b_{n1} = Σ_m a_m T_{m,n1} = Re a_0 T_{0,n1} + Σ_{m>0} 2 Re(a_m T_{m,n1}), T_{−m} = conj T_m.
Eigen::MatrixXd cartesian_coefficients(const ShapeletModel& model) {
    const int n_max = model.n_max;
    Eigen::MatrixXd b = Eigen::MatrixXd::Zero(n_max + 1, n_max + 1);
    for (int n = 0; n <= n_max; ++n) {
        const Eigen::MatrixXcd& t = polar_cartesian_matrix(n);
        for (int n1 = 0; n1 <= n; ++n1) {
            double sum = 0.0;
            for (int m = n % 2; m <= n; m += 2) {
                const double term = (model.at(n, m) * t((n + m) / 2, n1)).real();
                sum += (m == 0) ? term : 2.0 * term;
            }
            b(n1, n - n1) = sum;
        }
    }
    return b;
}

/// The inverse: a_m = Σ_{n1} conj(T_{m,n1}) b_{n1} (T unitary), for orders 0..model.n_max.
void set_polar_coefficients(const Eigen::MatrixXd& b, ShapeletModel& model) {
    for (int n = 0; n <= model.n_max; ++n) {
        const Eigen::MatrixXcd& t = polar_cartesian_matrix(n);
        for (int m = n % 2; m <= n; m += 2) {
            Complex sum = 0.0;
            for (int n1 = 0; n1 <= n; ++n1) sum += std::conj(t((n + m) / 2, n1)) * b(n1, n - n1);
            model.at(n, m) = (m == 0) ? Complex(sum.real(), 0.0) : sum;
        }
    }
}

/// Σ_{n1+n2=n} b(n1, n2)² for n = 0..n_max: the energy of each order.
Eigen::VectorXd order_energies(const Eigen::MatrixXd& b, int n_max) {
    Eigen::VectorXd energy = Eigen::VectorXd::Zero(n_max + 1);
    for (int n = 0; n <= n_max; ++n)
        for (int n1 = 0; n1 <= n; ++n1) energy(n) += b(n1, n - n1) * b(n1, n - n1);
    return energy;
}

/// Smallest N ≤ n_max with ‖g‖² − Σ_{n≤N} energy(n) ≤ target, or −1.
int smallest_order(const Eigen::VectorXd& energy, double norm2, double target) {
    double kept = 0.0;
    for (int n = 0; n < energy.size(); ++n) {
        kept += energy(n);
        if (norm2 - kept <= target) return n;
    }
    return -1;
}

/// The map of docs/algorithms.md#transforms in the frame of the quadrature.
struct AffineMap {
    Eigen::Matrix2d a;
    Eigen::Vector2d e;  ///< c + d − c_o, pixels
    double beta_in, beta_out, det_abs;
};

/// out(i, n) = φ_n(u_i) for n = 0..n_max: the recurrence of basis1d.hpp run down the columns,
/// vectorised across points. It starts from φ_0 = π^{−1/4} e^{−u²/2}, which is a normal
/// number for |u| < 37; beyond that the points are redone by hermite_functions (which
/// rescales). Every |φ_n| ≤ π^{−1/4}, so nothing overflows.
void hermite_columns(const Eigen::ArrayXd& u, int n_max, Eigen::MatrixXd& out) {
    constexpr double kPiQuarterInv = 0.75112554446494248286;  // π^{−1/4}
    out.resize(u.size(), n_max + 1);
    out.col(0) = kPiQuarterInv * (-0.5 * u.square()).exp();
    if (n_max >= 1) out.col(1) = std::sqrt(2.0) * u * out.col(0).array();
    for (int n = 1; n < n_max; ++n)
        out.col(n + 1) = std::sqrt(2.0 / (n + 1)) * u * out.col(n).array() -
                         std::sqrt(double(n) / (n + 1)) * out.col(n - 1).array();
    std::vector<double> row;
    for (Eigen::Index i = 0; i < u.size(); ++i)
        if (!(std::abs(u(i)) < 37.0)) {
            row.resize(n_max + 1);
            hermite_functions(u(i), n_max, row.data());
            for (int n = 0; n <= n_max; ++n) out(i, n) = row[n];
        }
}

/// Fill ws.b_out with b_o(l1, l2), l1 + l2 ≤ n_out (zero elsewhere), by the exact tensor
/// Gauss–Hermite rule of docs/algorithms.md#transforms.
void project_cartesian(const Eigen::MatrixXd& b_in, int n_in, const AffineMap& map, int n_out,
                       ProjectionWorkspace& ws) {
    // Complete the square: exponent −½ uᵀQu − hᵀu, minimum at u* = −Q⁻¹h.
    const double inv_bo2 = 1.0 / (map.beta_out * map.beta_out);
    const Eigen::Matrix2d q = map.a.transpose() * map.a * inv_bo2 +
                              Eigen::Matrix2d::Identity() / (map.beta_in * map.beta_in);
    const Eigen::Vector2d centre = -q.inverse() * (map.a.transpose() * map.e * inv_bo2);
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(q);
    const Eigen::Vector2d step = (2.0 / eigen.eigenvalues().array()).sqrt();
    const Eigen::Matrix2d to_u = eigen.eigenvectors() * step.asDiagonal();  // u = u* + to_u t
    // K nodes per axis integrate degree ≤ 2K − 1 ≥ n_in + n_out exactly.
    const GaussHermite& rule = gauss_hermite((n_in + n_out) / 2 + 1);
    const int k = int(rule.nodes.size()), nodes = k * k;
    Eigen::Map<const Eigen::ArrayXd> t(rule.nodes.data(), k), w(rule.weights.data(), k);
    // Node (i, j) ↦ row i·k + j: t = (t_i, t_j), u = u* + to_u t, X = A u + e (pixels).
    Eigen::ArrayXd ti(nodes), tj(nodes);
    ws.values.resize(nodes);
    for (int i = 0; i < k; ++i) {
        ti.segment(i * k, k).setConstant(t(i));
        tj.segment(i * k, k) = t;
        ws.values.segment(i * k, k) = w(i) * w;
    }
    const Eigen::ArrayXd ux = centre.x() + to_u(0, 0) * ti + to_u(0, 1) * tj;
    const Eigen::ArrayXd uy = centre.y() + to_u(1, 0) * ti + to_u(1, 1) * tj;
    hermite_columns(ux / map.beta_in, n_in, ws.in_x);
    hermite_columns(uy / map.beta_in, n_in, ws.in_y);
    hermite_columns((map.a(0, 0) * ux + map.a(0, 1) * uy + map.e.x()) / map.beta_out, n_out,
                    ws.out_x);
    hermite_columns((map.a(1, 0) * ux + map.a(1, 1) * uy + map.e.y()) / map.beta_out, n_out,
                    ws.out_y);
    // f at the nodes, Σ b(n1, n2) φ_{n1}(u_x) φ_{n2}(u_y); times the weights, the Jacobian
    // |det to_u|, |det A| and the β^{−1/2} normalisations of the four 1D functions.
    ws.partial.noalias() = ws.in_y * b_in.transpose();
    const double scale = std::abs(to_u.determinant()) * map.det_abs /
                         (map.beta_in * map.beta_out);
    ws.values.array() *= (ws.in_x.array() * ws.partial.array()).rowwise().sum() * scale;
    ws.partial.noalias() = ws.values.asDiagonal() * ws.out_y;
    ws.b_out.noalias() = ws.out_x.transpose() * ws.partial;
    for (int l1 = 0; l1 <= n_out; ++l1)
        for (int l2 = n_out - l1 + 1; l2 <= n_out; ++l2) ws.b_out(l1, l2) = 0.0;
}

/// A pure shift onto a basis that moves with it (e = 0, A = I, same β): the coefficients
/// themselves, truncated or padded, at the output centre.
Projection identity_projection(const ShapeletModel& model, const OutputBasis& basis,
                               const ProjectionOptions& options, double norm2) {
    int n_out = options.n_out;
    if (n_out < 0) {
        Eigen::VectorXd energy = Eigen::VectorXd::Zero(model.n_max + 1);
        int k = 0;
        for (const auto& [n, m] : polar_indices(model.n_max))
            energy(n) += (m == 0 ? 1.0 : 2.0) * std::norm(model.coeffs[k++]);
        const int n = smallest_order(energy, norm2, options.tolerance * norm2);
        n_out = (n >= 0) ? n : model.n_max;
    }
    Projection out;
    out.model = with_n_max(model, n_out);
    out.model.x = basis.x;
    out.model.y = basis.y;
    out.norm2 = norm2;
    int k = 0;
    for (const auto& [n, m] : polar_indices(model.n_max)) {  // the dropped terms, exactly
        if (n > n_out) out.truncation_error += (m == 0 ? 1.0 : 2.0) * std::norm(model.coeffs[k]);
        ++k;
    }
    return out;
}

/// The next trial order: extrapolate the decay of the truncation error over the last four
/// orders (asymptotically geometric) to the target, plus two; else grow by half.
int next_trial(const Eigen::VectorXd& energy, double norm2, double target, int trial, int cap) {
    const double now = norm2 - energy.sum();
    const double before = (trial >= 4) ? now + energy.tail(4).sum() : 0.0;
    int extra = std::max(4, trial / 2);
    if (trial >= 4 && now > 0.0 && before > now) {
        const double per_order = std::log(now / before) / 4.0;  // < 0
        const double needed = std::log(target / now) / per_order;
        if (std::isfinite(needed)) extra = std::clamp(int(std::ceil(needed)) + 2, 2, extra);
    }
    return std::min(cap, trial + extra);
}

/// The order-N search of docs/algorithms.md#transforms; leaves the chosen projection in ws.b_out.
int project_to_tolerance(const Eigen::MatrixXd& b_in, int n_in, const AffineMap& map,
                         const ProjectionOptions& options, double norm2,
                         ProjectionWorkspace& ws) {
    const int cap = options.n_out_max;
    const double target = options.tolerance * norm2;
    int trial = std::min(cap, n_in + 4);
    for (;;) {
        project_cartesian(b_in, n_in, map, trial, ws);
        const Eigen::VectorXd energy = order_energies(ws.b_out, trial);
        const int n = smallest_order(energy, norm2, target);
        if (n >= 0 || trial == cap) {
            const int n_out = (n >= 0) ? n : cap;
            // Coefficients of order ≤ n_out do not depend on the trial order: keep them.
            ws.b_out.conservativeResize(n_out + 1, n_out + 1);
            return n_out;
        }
        trial = next_trial(energy, norm2, target, trial, cap);
    }
}

void check_options(const ProjectionOptions& options) {
    require(options.n_out <= 1000 && options.n_out_max >= 0 && options.n_out_max <= 1000,
            "projection: n_out and n_out_max must lie in [0, 1000]");
    require(options.n_out >= 0 || options.tolerance >= 1e-14,
            "projection: tolerance must be >= 1e-14 (the rounding floor of Parseval's "
            "difference), got " + std::to_string(options.tolerance));
}

void finish(Projection& out, double scale) {
    // An overall factor on g scales coefficients by it and squared norms by its square.
    if (scale != 1.0) {
        for (Complex& a : out.model.coeffs) a *= scale;
        out.norm2 *= scale * scale;
        out.truncation_error *= scale * scale;
    }
    out.truncation_error = std::max(0.0, out.truncation_error);
    out.relative_error = out.norm2 > 0.0 ? out.truncation_error / out.norm2 : 0.0;
}

}  // namespace

Projection project_affine(const ShapeletModel& model, const Eigen::Matrix2d& a,
                          const Eigen::Vector2d& shift, const OutputBasis& basis,
                          const ProjectionOptions& options, ProjectionWorkspace* workspace) {
    require_sized(model, "project_affine");
    check_options(options);
    const double det = a.determinant();
    require(a.allFinite() && std::isfinite(det) && det != 0.0,
            "project_affine: the matrix must be finite and invertible");
    require(shift.allFinite() && std::isfinite(basis.x) && std::isfinite(basis.y),
            "project_affine: shift and output centre must be finite");
    require(basis.beta_pix > 0.0 && std::isfinite(basis.beta_pix),
            "project_affine: output beta must be finite and > 0");
    const AffineMap map{a, Eigen::Vector2d(model.x + shift.x() - basis.x,
                                           model.y + shift.y() - basis.y),
                        model.beta_pix, basis.beta_pix, std::abs(det)};
    const double norm2 = map.det_abs * squared_norm(model);  // ‖g‖² = |det A| ‖f‖²
    Projection out;
    if (a == Eigen::Matrix2d::Identity() && map.e.isZero(0.0) &&
        basis.beta_pix == model.beta_pix) {
        out = identity_projection(model, basis, options, norm2);
    } else {
        ProjectionWorkspace local;
        ProjectionWorkspace& ws = workspace ? *workspace : local;
        const Eigen::MatrixXd b_in = cartesian_coefficients(model);
        int n_out = options.n_out;
        if (n_out >= 0)
            project_cartesian(b_in, model.n_max, map, n_out, ws);
        else
            n_out = project_to_tolerance(b_in, model.n_max, map, options, norm2, ws);
        out.model = ShapeletModel(basis.x, basis.y, basis.beta_pix, n_out);
        set_polar_coefficients(ws.b_out, out.model);
        out.norm2 = norm2;
        out.truncation_error = norm2 - order_energies(ws.b_out, n_out).sum();
    }
    finish(out, 1.0);
    out.tolerance_met = out.relative_error <= options.tolerance;
    return out;
}

Projection affine_transform(const ShapeletModel& model, const Eigen::Matrix2d& a,
                            const Eigen::Vector2d& shift, const ProjectionOptions& options,
                            ProjectionWorkspace* workspace) {
    const OutputBasis basis{model.x + shift.x(), model.y + shift.y(),
                            model.beta_pix * std::sqrt(std::abs(a.determinant()))};
    return project_affine(model, a, shift, basis, options, workspace);
}

Projection translate(const ShapeletModel& model, double dx, double dy,
                     const ProjectionOptions& options, ProjectionWorkspace* workspace) {
    return project_affine(model, Eigen::Matrix2d::Identity(), Eigen::Vector2d(dx, dy),
                          OutputBasis{model.x, model.y, model.beta_pix}, options, workspace);
}

Projection recentre(const ShapeletModel& model, double x, double y,
                    const ProjectionOptions& options, ProjectionWorkspace* workspace) {
    return project_affine(model, Eigen::Matrix2d::Identity(), Eigen::Vector2d::Zero(),
                          OutputBasis{x, y, model.beta_pix}, options, workspace);
}

Projection change_beta(const ShapeletModel& model, double beta_pix,
                       const ProjectionOptions& options, ProjectionWorkspace* workspace) {
    return project_affine(model, Eigen::Matrix2d::Identity(), Eigen::Vector2d::Zero(),
                          OutputBasis{model.x, model.y, beta_pix}, options, workspace);
}

Eigen::Matrix2d shear_matrix(double g1, double g2) {
    const double g_sq = g1 * g1 + g2 * g2;
    require(std::isfinite(g_sq) && g_sq < 1.0, "shear: |g| must be < 1");
    Eigen::Matrix2d s;
    s << 1.0 + g1, g2, g2, 1.0 - g1;
    return s / std::sqrt(1.0 - g_sq);
}

Projection shear(const ShapeletModel& model, double g1, double g2,
                 const ProjectionOptions& options, ProjectionWorkspace* workspace) {
    return project_affine(model, shear_matrix(g1, g2), Eigen::Vector2d::Zero(),
                          OutputBasis{model.x, model.y, model.beta_pix}, options, workspace);
}

double magnification(const Lensing& lensing) {
    const double g_sq = lensing.g1 * lensing.g1 + lensing.g2 * lensing.g2;
    require(std::isfinite(g_sq) && g_sq < 1.0, "lens: |g| must be < 1");
    require(std::isfinite(lensing.kappa) && lensing.kappa < 1.0, "lens: kappa must be < 1");
    const double one_minus_kappa = 1.0 - lensing.kappa;
    return 1.0 / (one_minus_kappa * one_minus_kappa * (1.0 - g_sq));
}

Eigen::Matrix2d lensing_matrix(const Lensing& lensing) {
    const double mu = magnification(lensing);
    return std::sqrt(mu) * shear_matrix(lensing.g1, lensing.g2);
}

Projection lens(const ShapeletModel& model, const Lensing& lensing,
                const ProjectionOptions& options, ProjectionWorkspace* workspace) {
    const double mu = magnification(lensing);
    Projection out = project_affine(model, lensing_matrix(lensing), Eigen::Vector2d::Zero(),
                                    OutputBasis{model.x, model.y, model.beta_pix * std::sqrt(mu)},
                                    options, workspace);
    // Dividing g by μ scales both squared norms alike: the relative error is unchanged.
    if (lensing.conserve_flux) finish(out, 1.0 / mu);
    return out;
}

}  // namespace shapesim
