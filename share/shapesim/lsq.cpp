#include "shapesim/lsq.hpp"

#include "shapesim/basis1d.hpp"
#include "shapesim/convolve.hpp"
#include "shapesim/error.hpp"
#include "shapesim/polar.hpp"
#include "shapesim/render.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>

namespace shapesim {

namespace {
// Checks the inputs; returns the effective weights (0 where a pixel is not used), the image
// with unused pixels zeroed, and the count of used pixels.
struct CleanStamp {
    Eigen::MatrixXd weight, image;  // ny × nx
    long used = 0;
};

CleanStamp clean_stamp(const ImageArray& image, const ImageArray& weight, const MaskArray* mask) {
    if (weight.rows() != image.rows() || weight.cols() != image.cols())
        throw Error("weight map shape differs from the image", {}, 0, "weight");
    if (mask && (mask->rows() != image.rows() || mask->cols() != image.cols()))
        throw Error("mask shape differs from the image", {}, 0, "mask");
    CleanStamp s{Eigen::MatrixXd::Zero(image.rows(), image.cols()),
                 Eigen::MatrixXd::Zero(image.rows(), image.cols()), 0};
    for (Eigen::Index j = 0; j < image.rows(); ++j)
        for (Eigen::Index i = 0; i < image.cols(); ++i) {
            const double w = weight(j, i);
            if (w < 0.0 || std::isinf(w))
                throw Error("weights must be finite and >= 0, got " + std::to_string(w) +
                                " at pixel " + std::to_string(i + 1) + "," + std::to_string(j + 1),
                            {}, 0, "weight");
            if (!(w > 0.0) || !std::isfinite(image(j, i)) || (mask && (*mask)(j, i) != 0)) continue;
            s.weight(j, i) = w;
            s.image(j, i) = image(j, i);
            ++s.used;
        }
    return s;
}

struct Solution {
    Eigen::VectorXd cart;      // packed Cartesian coefficients
    Eigen::MatrixXd cov_cart;  // their covariance
};

// The normal equations AᵀWA c = AᵀW I, built separably (see lsq.hpp).
struct NormalSystem {
    Eigen::MatrixXd normal;
    Eigen::VectorXd rhs;
};

NormalSystem normal_system(const CleanStamp& s, const Eigen::MatrixXd& phi_x,
                           const Eigen::MatrixXd& phi_y, int n_max) {
    const int nb = n_max + 1, nx = int(phi_x.cols()), ny = int(phi_y.cols());
    Eigen::MatrixXd x2(nb * nb, nx), y2(nb * nb, ny);  // products Φ(n,·)Φ(m,·)
    for (int n = 0; n < nb; ++n)
        for (int m = 0; m < nb; ++m) {
            x2.row(n * nb + m) = phi_x.row(n).cwiseProduct(phi_x.row(m));
            y2.row(n * nb + m) = phi_y.row(n).cwiseProduct(phi_y.row(m));
        }
    const Eigen::MatrixXd h = (x2 * s.weight.transpose()) * y2.transpose();
    const Eigen::MatrixXd rhs_b =
        phi_x * s.image.cwiseProduct(s.weight).transpose() * phi_y.transpose();
    const int nc = real_count(n_max);
    NormalSystem system{Eigen::MatrixXd(nc, nc), Eigen::VectorXd(nc)};
    for (int n = 0; n <= n_max; ++n)
        for (int n1 = 0; n1 <= n; ++n1) {
            const int row = cartesian_index(n1, n - n1);
            system.rhs(row) = rhs_b(n1, n - n1);
            for (int m = 0; m <= n_max; ++m)
                for (int m1 = 0; m1 <= m; ++m1)
                    system.normal(row, cartesian_index(m1, m - m1)) =
                        h(n1 * nb + m1, (n - n1) * nb + (m - m1));
        }
    return system;
}

// LDLT solve of the normal equations; empty when ill-conditioned (unless `required`).
std::optional<Solution> solve_normal(const NormalSystem& system, bool required) {
    const Eigen::Index nc = system.normal.rows();
    Eigen::LDLT<Eigen::MatrixXd> ldlt(system.normal);
    if (!required && (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-10)))
        return std::nullopt;
    return Solution{ldlt.solve(system.rhs), ldlt.solve(Eigen::MatrixXd::Identity(nc, nc))};
}

// Column-pivoting QR of the weighted design matrix (times `transform` when given: the
// coefficients fitted are transform's columns); throws when rank-deficient.
Solution solve_qr(const CleanStamp& s, const Eigen::MatrixXd& phi_x, const Eigen::MatrixXd& phi_y,
                  int n_max, const Eigen::MatrixXd* transform = nullptr) {
    const int nb = real_count(n_max);
    Eigen::MatrixXd basis(s.used, nb);
    Eigen::VectorXd rhs(s.used);
    long r = 0;
    for (Eigen::Index j = 0; j < s.weight.rows(); ++j)
        for (Eigen::Index i = 0; i < s.weight.cols(); ++i) {
            if (s.weight(j, i) == 0.0) continue;
            const double sw = std::sqrt(s.weight(j, i));
            for (int n = 0; n <= n_max; ++n)
                for (int n1 = 0; n1 <= n; ++n1)
                    basis(r, cartesian_index(n1, n - n1)) = sw * phi_x(n1, i) * phi_y(n - n1, j);
            rhs(r++) = sw * s.image(j, i);
        }
    const Eigen::MatrixXd design = transform ? Eigen::MatrixXd(basis * *transform) : basis;
    const Eigen::Index nc = design.cols();
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(design);
    if (qr.rank() < nc)
        throw Error("the pixels do not constrain every coefficient (rank " +
                    std::to_string(qr.rank()) + " of " + std::to_string(nc) +
                    "): lower n_max or change beta");
    // (AᵀWA)⁻¹ = P R⁻¹ R⁻ᵀ Pᵀ with R the leading triangle of the factor.
    const Eigen::MatrixXd r_inverse = qr.matrixR().topLeftCorner(nc, nc)
                                          .triangularView<Eigen::Upper>()
                                          .solve(Eigen::MatrixXd::Identity(nc, nc));
    const auto& p = qr.colsPermutation();
    return Solution{qr.solve(rhs), p * (r_inverse * r_inverse.transpose()) * p.transpose()};
}

// The fit's polar model, covariance, images and χ² from a Cartesian solution; `observed` is
// the Cartesian model whose image the data are compared with.
ShapeletFit finish_fit(const ImageArray& image, const CleanStamp& s, const Solution& sol,
                       double x, double y, double beta_pix, int n_max,
                       const CartesianModel& observed) {
    ShapeletFit fit;
    // B cov Bᵀ with B the (block-diagonal) Cartesian → real parameter map.
    constexpr BasisChange to_real = BasisChange::cartesian_to_real;
    fit.model = ShapeletModel(x, y, beta_pix, n_max);
    set_real_parameters(fit.model, change_basis_rows(to_real, sol.cart, n_max));
    fit.covariance = change_basis_rows(
        to_real, change_basis_rows(to_real, sol.cov_cart, n_max).transpose(), n_max);
    const int nx = int(image.cols()), ny = int(image.rows());
    fit.model_image = render_stamp(observed, nx, ny);
    fit.residual = image - fit.model_image;
    fit.chi2 = (s.weight.array() * (s.image.array() - fit.model_image).square()).sum();
    fit.pixels_used = s.used;
    fit.dof = s.used - real_count(n_max);
    fit.chi2r = fit.chi2 / double(fit.dof);
    return fit;
}

void check_fit_inputs(int n_max, double beta_pix) {
    require(n_max >= 0, "fit_shapelets: n_max must be >= 0");
    if (!(beta_pix > 0.0) || !std::isfinite(beta_pix))
        throw Error("must be finite and > 0, got " + std::to_string(beta_pix), {}, 0, "beta");
}

void check_pixels(const CleanStamp& s, int n_max) {
    const int nc = real_count(n_max);
    if (s.used <= nc)
        throw Error(std::to_string(s.used) + " usable pixels for " + std::to_string(nc) +
                    " coefficients (n_max " + std::to_string(n_max) + ")");
}
}  // namespace

ShapeletFit fit_shapelets(const ImageArray& image, const ImageArray& weight,
                          const MaskArray* mask, double x, double y, double beta_pix,
                          int n_max, LsqSolver solver) {
    check_fit_inputs(n_max, beta_pix);
    const CleanStamp s = clean_stamp(image, weight, mask);
    check_pixels(s, n_max);
    const int nx = int(image.cols()), ny = int(image.rows());
    const Eigen::MatrixXd phi_x = pixel_basis_1d(n_max, beta_pix, 1.0 - x, nx);
    const Eigen::MatrixXd phi_y = pixel_basis_1d(n_max, beta_pix, 1.0 - y, ny);
    std::optional<Solution> sol;
    if (solver != LsqSolver::qr)
        sol = solve_normal(normal_system(s, phi_x, phi_y, n_max), solver == LsqSolver::normal);
    const LsqSolver used = sol ? LsqSolver::normal : LsqSolver::qr;
    if (!sol) sol = solve_qr(s, phi_x, phi_y, n_max);
    CartesianModel observed(x, y, beta_pix, n_max);
    observed.b = unpack_cartesian(sol->cart, n_max);
    ShapeletFit fit = finish_fit(image, s, *sol, x, y, beta_pix, n_max, observed);
    fit.solver_used = used;
    return fit;
}

ShapeletFit fit_convolved_shapelets(const ImageArray& image, const ImageArray& weight,
                                    const MaskArray* mask, double x, double y, double beta_pix,
                                    int n_max, const CartesianModel& psf, LsqSolver solver) {
    check_fit_inputs(n_max, beta_pix);
    const CleanStamp s = clean_stamp(image, weight, mask);
    check_pixels(s, n_max);
    const int n_out = n_max + psf.n_max;
    const double gamma = convolved_beta(beta_pix, psf.beta_pix);
    const Eigen::MatrixXd transform = cartesian_convolution_matrix(psf, beta_pix, n_max);
    const int nx = int(image.cols()), ny = int(image.rows());
    const Eigen::MatrixXd phi_x = pixel_basis_1d(n_out, gamma, 1.0 - x, nx);
    const Eigen::MatrixXd phi_y = pixel_basis_1d(n_out, gamma, 1.0 - y, ny);
    std::optional<Solution> sol;
    if (solver != LsqSolver::qr) {
        const NormalSystem full = normal_system(s, phi_x, phi_y, n_out);
        const NormalSystem system{transform.transpose() * full.normal * transform,
                                  transform.transpose() * full.rhs};
        sol = solve_normal(system, solver == LsqSolver::normal);
    }
    const LsqSolver used = sol ? LsqSolver::normal : LsqSolver::qr;
    if (!sol) sol = solve_qr(s, phi_x, phi_y, n_out, &transform);
    CartesianModel observed(x, y, gamma, n_out);
    observed.b = unpack_cartesian(transform * sol->cart, n_out);
    ShapeletFit fit = finish_fit(image, s, *sol, x, y, beta_pix, n_max, observed);
    fit.solver_used = used;
    return fit;
}

ShapeletFit fit_shape_amplitude(const ImageArray& image, const ImageArray& weight,
                                const MaskArray* mask, double x, double y,
                                const ShapeletModel& shape, const CartesianModel* psf) {
    const int n_max = shape.n_max;
    const double beta_pix = shape.beta_pix;
    check_fit_inputs(n_max, beta_pix);
    const CleanStamp s = clean_stamp(image, weight, mask);
    check_pixels(s, 0);
    const Eigen::VectorXd unit = pack_cartesian(to_cartesian(shape).b, n_max);
    // The shape as the data see it: through the PSF's exact convolution map, or as it is.
    const int n_out = psf ? n_max + psf->n_max : n_max;
    const double scale = psf ? convolved_beta(beta_pix, psf->beta_pix) : beta_pix;
    const Eigen::VectorXd seen =
        psf ? Eigen::VectorXd(cartesian_convolution_matrix(*psf, beta_pix, n_max) * unit) : unit;
    // One basis function: its image u, then a = Σ w I u / Σ w u², Var a = 1 / Σ w u².
    CartesianModel observed(x, y, scale, n_out);
    observed.b = unpack_cartesian(seen, n_out);
    const Eigen::MatrixXd u = render_stamp(observed, int(image.cols()), int(image.rows())).matrix();
    const double normal = s.weight.cwiseProduct(u.cwiseProduct(u)).sum();
    if (!(normal > 0.0) || !std::isfinite(normal))
        throw Error("the shape leaves no light on the stamp's usable pixels");
    const double a = s.weight.cwiseProduct(s.image).cwiseProduct(u).sum() / normal;
    const Solution sol{a * unit, unit * unit.transpose() / normal};
    observed.b *= a;
    ShapeletFit fit = finish_fit(image, s, sol, x, y, beta_pix, n_max, observed);
    // The rank-one covariance in the real parameters directly: a diagonal rounded from the
    // Cartesian one can fall a hair below zero.
    const Eigen::VectorXd real = change_basis_rows(BasisChange::cartesian_to_real, unit, n_max);
    fit.covariance = real * real.transpose() / normal;
    fit.dof = s.used - 1;
    fit.chi2r = fit.chi2 / double(fit.dof);
    fit.solver_used = LsqSolver::normal;
    return fit;
}

namespace {
// (R b)(p) = Σ_d ξ(d) b(p + d) over the stamp (b is zero beyond it).
Eigen::MatrixXd correlate(const Eigen::MatrixXd& b, const NoiseCorrelation& xi) {
    const Eigen::Index ny = b.rows(), nx = b.cols();
    Eigen::MatrixXd out = Eigen::MatrixXd::Zero(ny, nx);
    for (int dy = -xi.radius; dy <= xi.radius; ++dy)
        for (int dx = -xi.radius; dx <= xi.radius; ++dx) {
            const double w = xi.at(dx, dy);
            const Eigen::Index j0 = std::max<Eigen::Index>(0, -dy),
                               i0 = std::max<Eigen::Index>(0, -dx);
            const Eigen::Index h = std::min(ny, ny - dy) - j0, wd = std::min(nx, nx - dx) - i0;
            if (w == 0.0 || h <= 0 || wd <= 0) continue;
            out.block(j0, i0, h, wd) += w * b.block(j0 + dy, i0 + dx, h, wd);
        }
    return out;
}
}  // namespace

double noise_take_up(const ImageArray& image, const ImageArray& weight, const MaskArray* mask,
                     double x, double y, double beta_pix, int n_max, const NoiseCorrelation& xi,
                     const CartesianModel* psf) {
    check_fit_inputs(n_max, beta_pix);
    require(xi.radius >= 0 &&
                xi.values.size() == std::size_t((2 * xi.radius + 1) * (2 * xi.radius + 1)),
            "noise_take_up: the correlation's values do not match its radius");
    const CleanStamp s = clean_stamp(image, weight, mask);
    check_pixels(s, n_max);
    // The design at the scale and order the data are fitted with (convolve.hpp for the PSF's).
    const int n_out = psf ? n_max + psf->n_max : n_max;
    const double scale = psf ? convolved_beta(beta_pix, psf->beta_pix) : beta_pix;
    const int nx = int(image.cols()), ny = int(image.rows());
    const Eigen::MatrixXd phi_x = pixel_basis_1d(n_out, scale, 1.0 - x, nx);
    const Eigen::MatrixXd phi_y = pixel_basis_1d(n_out, scale, 1.0 - y, ny);
    const Eigen::MatrixXd root = s.weight.cwiseSqrt();
    Eigen::MatrixXd normal = normal_system(s, phi_x, phi_y, n_out).normal;  // BᵀB
    const int nc = real_count(n_out);
    Eigen::MatrixXd spread(nc, nc);  // BᵀRB, column by column
    for (int n = 0; n <= n_out; ++n)
        for (int n1 = 0; n1 <= n; ++n1) {
            const Eigen::MatrixXd column =
                root.cwiseProduct(phi_y.row(n - n1).transpose() * phi_x.row(n1));
            const Eigen::MatrixXd projected =
                phi_y * root.cwiseProduct(correlate(column, xi)) * phi_x.transpose();
            const int k = cartesian_index(n1, n - n1);
            for (int m = 0; m <= n_out; ++m)
                for (int m1 = 0; m1 <= m; ++m1)
                    spread(cartesian_index(m1, m - m1), k) = projected(m - m1, m1);
        }
    if (psf) {
        const Eigen::MatrixXd map = cartesian_convolution_matrix(*psf, beta_pix, n_max);
        normal = map.transpose() * normal * map;
        spread = map.transpose() * spread * map;
    }
    return normal.ldlt().solve(spread).trace();
}

}  // namespace shapesim
