#include "shapesim/lsq.hpp"

#include "shapesim/basis1d.hpp"
#include "shapesim/error.hpp"
#include "shapesim/polar.hpp"
#include "shapesim/render.hpp"

#include <cmath>
#include <string>
#include <vector>

namespace shapesim {

namespace {
// Checks the inputs and lists the usable pixels (row-major index).
std::vector<long> usable_pixels(const ImageArray& image, const ImageArray& weight,
                                const MaskArray* mask) {
    if (weight.rows() != image.rows() || weight.cols() != image.cols())
        throw Error("weight map shape differs from the image", {}, 0, "weight");
    if (mask && (mask->rows() != image.rows() || mask->cols() != image.cols()))
        throw Error("mask shape differs from the image", {}, 0, "mask");
    std::vector<long> used;
    used.reserve(image.size());
    for (long p = 0; p < image.size(); ++p) {
        const double w = weight.data()[p];
        if (w < 0.0 || std::isinf(w))
            throw Error("weights must be finite and >= 0, got " + std::to_string(w) + " at pixel " +
                            std::to_string(p % image.cols() + 1) + "," +
                            std::to_string(p / image.cols() + 1),
                        {}, 0, "weight");
        if (!(w > 0.0) || !std::isfinite(image.data()[p])) continue;
        if (mask && mask->data()[p] != 0) continue;
        used.push_back(p);
    }
    return used;
}
}  // namespace

ShapeletFit fit_shapelets(const ImageArray& image, const ImageArray& weight,
                          const MaskArray* mask, double x, double y, double beta_pix,
                          int n_max) {
    require(n_max >= 0, "fit_shapelets: n_max must be >= 0");
    if (!(beta_pix > 0.0) || !std::isfinite(beta_pix))
        throw Error("must be finite and > 0, got " + std::to_string(beta_pix), {}, 0, "beta");
    const std::vector<long> used = usable_pixels(image, weight, mask);
    const int ncoeff = real_count(n_max);
    if (long(used.size()) <= ncoeff)
        throw Error(std::to_string(used.size()) + " usable pixels for " + std::to_string(ncoeff) +
                    " coefficients (n_max " + std::to_string(n_max) + ")");

    // Weighted design matrix on the pixel-integrated Cartesian basis.
    const int nx = int(image.cols()), ny = int(image.rows());
    const Eigen::MatrixXd phi_x = pixel_basis_1d(n_max, beta_pix, 1.0 - x, nx);
    const Eigen::MatrixXd phi_y = pixel_basis_1d(n_max, beta_pix, 1.0 - y, ny);
    Eigen::MatrixXd design(used.size(), ncoeff);
    Eigen::VectorXd rhs(used.size());
    for (size_t r = 0; r < used.size(); ++r) {
        const long i = used[r] % nx, j = used[r] / nx;
        const double sw = std::sqrt(weight.data()[used[r]]);
        for (int n = 0; n <= n_max; ++n)
            for (int n1 = 0; n1 <= n; ++n1)
                design(r, cartesian_index(n1, n - n1)) = sw * phi_x(n1, i) * phi_y(n - n1, j);
        rhs(r) = sw * image.data()[used[r]];
    }

    // Solve by column-pivoting QR; the rank check catches unconstrained basis functions.
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(design);
    if (qr.rank() < ncoeff)
        throw Error("the pixels do not constrain every coefficient (rank " +
                    std::to_string(qr.rank()) + " of " + std::to_string(ncoeff) +
                    "): lower n_max or change beta");
    const Eigen::VectorXd cart = qr.solve(rhs);
    // (AᵀA)⁻¹ = P R⁻¹ R⁻ᵀ Pᵀ with R the leading triangle of the factor.
    const auto r_factor = qr.matrixR().topLeftCorner(ncoeff, ncoeff).triangularView<Eigen::Upper>();
    Eigen::MatrixXd r_inverse = r_factor.solve(Eigen::MatrixXd::Identity(ncoeff, ncoeff));
    const Eigen::MatrixXd cov_permuted = r_inverse * r_inverse.transpose();
    const Eigen::MatrixXd cov_cart =
        qr.colsPermutation() * cov_permuted * qr.colsPermutation().transpose();

    ShapeletFit fit;
    const Eigen::MatrixXd& to_real = cartesian_to_real_matrix(n_max);
    fit.model = ShapeletModel(x, y, beta_pix, n_max);
    set_real_parameters(fit.model, to_real * cart);
    fit.covariance = to_real * cov_cart * to_real.transpose();
    fit.pixels_used = long(used.size());
    fit.dof = fit.pixels_used - ncoeff;
    fit.chi2 = (design * cart - rhs).squaredNorm();
    fit.chi2r = fit.chi2 / double(fit.dof);

    CartesianModel cart_model(x, y, beta_pix, n_max);
    cart_model.b = unpack_cartesian(cart, n_max);
    fit.model_image = render_stamp(cart_model, nx, ny);
    fit.residual = image - fit.model_image;
    return fit;
}

}  // namespace shapesim
