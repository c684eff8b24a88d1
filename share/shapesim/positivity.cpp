#include "shapesim/positivity.hpp"

#include "shapesim/render.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <mutex>

namespace shapesim {

namespace {

constexpr double grid_beta = 3.0;  // pixels, as hole_depth() and pixel_holes() draw

// The drawn basis of one n_max, B = Q R: a column per real parameter (Re a_{n,m}, and Im a_{n,m}
// for m > 0, in packed order), a row per pixel of the (2 half + 1)² grid.
struct DrawnBasis {
    int half = 0;
    Eigen::MatrixXd q;  // P × K, orthonormal columns
    Eigen::MatrixXd r;  // K × K, upper triangular
};

DrawnBasis make_basis(int n_max) {
    DrawnBasis b;
    b.half = int(std::ceil(grid_beta * (std::sqrt(2.0 * n_max + 1.0) + 2.0)));
    const int side = 2 * b.half + 1;
    ShapeletModel unit(b.half + 1.0, b.half + 1.0, grid_beta, n_max);
    const std::vector<PolarIndex> index = polar_indices(n_max);
    std::vector<Eigen::VectorXd> columns;
    for (std::size_t k = 0; k < index.size(); ++k)
        for (const Complex c : {Complex(1.0, 0.0), Complex(0.0, 1.0)}) {
            if (index[k].m == 0 && c.imag() != 0.0) continue;
            std::fill(unit.coeffs.begin(), unit.coeffs.end(), Complex(0.0, 0.0));
            unit.coeffs[k] = c;
            const ImageArray stamp = render_stamp(unit, side, side);
            columns.push_back(Eigen::Map<const Eigen::VectorXd>(stamp.data(), stamp.size()));
        }
    Eigen::MatrixXd design(Eigen::Index(side) * side, Eigen::Index(columns.size()));
    for (std::size_t j = 0; j < columns.size(); ++j) design.col(Eigen::Index(j)) = columns[j];
    const Eigen::HouseholderQR<Eigen::MatrixXd> qr(design);
    const Eigen::Index k = design.cols();
    b.q = qr.householderQ() * Eigen::MatrixXd::Identity(design.rows(), k);
    b.r = qr.matrixQR().topLeftCorner(k, k).triangularView<Eigen::Upper>();
    return b;
}

// One basis per n_max, built once and shared by every thread.
const DrawnBasis& basis(int n_max) {
    static std::mutex lock;
    static std::map<int, std::unique_ptr<DrawnBasis>> cache;
    const std::lock_guard<std::mutex> hold(lock);
    std::unique_ptr<DrawnBasis>& slot = cache[n_max];
    if (!slot) slot = std::make_unique<DrawnBasis>(make_basis(n_max));
    return *slot;
}

// The real parameters of a model's coefficients, in the basis' column order, and back.
Eigen::VectorXd parameters(const ShapeletModel& model) {
    const std::vector<PolarIndex> index = polar_indices(model.n_max);
    std::vector<double> out;
    for (std::size_t k = 0; k < index.size(); ++k) {
        out.push_back(model.coeffs[k].real());
        if (index[k].m != 0) out.push_back(model.coeffs[k].imag());
    }
    return Eigen::Map<const Eigen::VectorXd>(out.data(), Eigen::Index(out.size()));
}

void set_parameters(ShapeletModel& model, const Eigen::VectorXd& p) {
    const std::vector<PolarIndex> index = polar_indices(model.n_max);
    Eigen::Index j = 0;
    for (std::size_t k = 0; k < index.size(); ++k) {
        const double re = p(j++);
        model.coeffs[k] = Complex(re, index[k].m != 0 ? p(j++) : 0.0);
    }
}

double negative_over_total(const Eigen::VectorXd& image) {
    const double total = image.sum();
    return total > 0.0 ? -image.cwiseMin(0.0).sum() / total
                       : std::numeric_limits<double>::infinity();
}

}  // namespace

PositiveModel nearest_non_negative(const ShapeletModel& model, double tolerance,
                                   int max_iterations) {
    PositiveModel out;
    out.model = model;
    if (model.n_max == 0) return out;  // a Gaussian: positive wherever its flux is
    const DrawnBasis& b = basis(model.n_max);
    const Eigen::VectorXd start = b.r * parameters(model);  // Qᵀ x₀ of the drawn image x₀
    Eigen::VectorXd z = start;
    Eigen::VectorXd y = b.q * z;
    out.negative_before = out.negative_after = negative_over_total(y);
    if (!(out.negative_before > tolerance) || !std::isfinite(out.negative_before)) return out;
    // Dykstra: the span's projection is linear (no correction term), the clip's keeps one.
    Eigen::VectorXd correction = Eigen::VectorXd::Zero(y.size());
    while (out.iterations < max_iterations) {
        const Eigen::VectorXd moved = y + correction;
        const Eigen::VectorXd clipped = moved.cwiseMax(0.0);
        correction = moved - clipped;
        z = b.q.transpose() * clipped;
        y = b.q * z;
        ++out.iterations;
        out.negative_after = negative_over_total(y);
        if (out.negative_after <= tolerance) break;
    }
    const Eigen::VectorXd p = b.r.triangularView<Eigen::Upper>().solve(z);
    set_parameters(out.model, p);
    out.change = (z - start).norm() / start.norm();
    return out;
}

}  // namespace shapesim
