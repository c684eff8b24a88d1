#include "shapesim/deconvolution.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/error.hpp"

#include <cmath>
#include <limits>

namespace shapesim {

Eigen::MatrixXd symmetric_sqrt(const Eigen::MatrixXd& m, bool inverse) {
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(m);
    if (eigen.info() != Eigen::Success) throw Error("no eigen-decomposition of a covariance");
    Eigen::VectorXd values = eigen.eigenvalues();
    // Below rounding of the largest: zero (a direction the matrix does not span).
    const double floor = 64.0 * std::numeric_limits<double>::epsilon() *
                         std::max(values.cwiseAbs().maxCoeff(), std::numeric_limits<double>::min());
    for (Eigen::Index i = 0; i < values.size(); ++i) {
        const double v = values(i) > floor ? values(i) : 0.0;
        values(i) = v > 0.0 ? (inverse ? 1.0 / std::sqrt(v) : std::sqrt(v)) : 0.0;
    }
    return eigen.eigenvectors() * values.asDiagonal() * eigen.eigenvectors().transpose();
}

namespace {

void check_inputs(const std::vector<Eigen::VectorXd>& points,
                  const std::vector<Eigen::MatrixXd>& noise) {
    if (points.size() < 2) throw Error("deconvolution needs at least two points");
    if (noise.size() != points.size()) throw Error("deconvolution: one noise matrix per point");
    const Eigen::Index d = points.front().size();
    if (d < 1) throw Error("deconvolution: points have no dimension");
    for (std::size_t i = 0; i < points.size(); ++i) {
        if (points[i].size() != d || noise[i].rows() != d || noise[i].cols() != d)
            throw Error("deconvolution: point " + std::to_string(i) + "'s dimension differs");
        if (!points[i].allFinite() || !noise[i].allFinite())
            throw Error("deconvolution: point " + std::to_string(i) + " is not finite");
    }
}

}  // namespace

GaussianPopulation deconvolve_gaussian(const std::vector<Eigen::VectorXd>& points,
                                       const std::vector<Eigen::MatrixXd>& noise,
                                       int max_iterations) {
    check_inputs(points, noise);
    const Eigen::Index d = points.front().size();
    const double n = double(points.size());
    GaussianPopulation pop;
    pop.mean = Eigen::VectorXd::Zero(d);
    for (const auto& x : points) pop.mean += x / n;
    pop.covariance = Eigen::MatrixXd::Zero(d, d);
    for (const auto& x : points) pop.covariance += (x - pop.mean) * (x - pop.mean).transpose() / n;
    // A start inside the cone: EM keeps V positive definite when it starts so.
    pop.covariance.diagonal().array() +=
        1e-9 * std::max(pop.covariance.trace() / double(d), 1e-300);

    const double log_2pi = std::log(2.0 * pi);
    double previous = -std::numeric_limits<double>::infinity();
    Eigen::VectorXd mean_b(d);
    Eigen::MatrixXd scatter(d, d);
    std::vector<Eigen::VectorXd> b(points.size());
    for (pop.iterations = 0; pop.iterations < max_iterations; ++pop.iterations) {
        double log_l = 0.0;
        scatter.setZero();
        mean_b.setZero();
        for (std::size_t i = 0; i < points.size(); ++i) {
            const Eigen::LDLT<Eigen::MatrixXd> t((pop.covariance + noise[i]).eval());
            if (t.info() != Eigen::Success || !(t.vectorD().minCoeff() > 0.0))
                throw Error("deconvolution: V + S is singular at point " + std::to_string(i));
            const Eigen::VectorXd r = points[i] - pop.mean;
            const Eigen::VectorXd t_r = t.solve(r);
            log_l -= 0.5 * (t.vectorD().array().log().sum() + r.dot(t_r) + double(d) * log_2pi);
            b[i] = pop.mean + pop.covariance * t_r;
            // B_i = V − V T⁻¹ V, summed.
            scatter += pop.covariance - pop.covariance * t.solve(pop.covariance);
            mean_b += b[i] / n;
        }
        pop.log_likelihood = log_l;
        if (log_l - previous <= 1e-12 * (1.0 + std::abs(log_l))) {
            pop.converged = true;
            break;
        }
        previous = log_l;
        for (const auto& bi : b) scatter += (bi - mean_b) * (bi - mean_b).transpose();
        pop.mean = mean_b;
        pop.covariance = 0.5 * (scatter + scatter.transpose()) / n;
    }
    return pop;
}

Eigen::VectorXd denoise(const GaussianPopulation& population, const Eigen::VectorXd& point,
                        const Eigen::MatrixXd& noise) {
    const Eigen::Index d = population.mean.size();
    if (point.size() != d || noise.rows() != d || noise.cols() != d)
        throw Error("denoise: the point's dimension differs from the population's");
    if (noise.isZero(0.0)) return point;
    const Eigen::MatrixXd t = population.covariance + noise;
    const Eigen::MatrixXd t_half = symmetric_sqrt(t), t_inv_half = symmetric_sqrt(t, true);
    const Eigen::MatrixXd middle = symmetric_sqrt(t_half * population.covariance * t_half);
    const Eigen::MatrixXd a = t_inv_half * middle * t_inv_half;
    return population.mean + a * (point - population.mean);
}

}  // namespace shapesim
