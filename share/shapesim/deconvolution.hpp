// A population seen through noise, and the population without it (the colours of jointly
// fitted galaxies). Each x_i = v_i + ε_i, v_i ~ N(μ, V), ε_i ~ N(0, S_i) with S_i known:
// deconvolve_gaussian finds μ and V by "extreme deconvolution" (Bovy, Hogg & Roweis 2011,
// §2); denoise moves x_i by the least-displacement map from N(μ, V + S_i) to N(μ, V).
// Derivation: docs/algorithms.md#denoised-colours
#pragma once

#include <Eigen/Dense>

#include <vector>

namespace shapesim {

struct GaussianPopulation {
    Eigen::VectorXd mean;
    Eigen::MatrixXd covariance;  ///< V, the population's own (noise removed)
    double log_likelihood = 0.0; ///< Σ_i ln N(x_i; μ, V + S_i) (at the result when converged)
    int iterations = 0;
    bool converged = false;      ///< the likelihood stopped rising (relative 1e-12) in time
};

/// μ and V of the population behind `points` with noise covariances `noise` (one per point,
/// symmetric positive semi-definite; same dimension). At least two points. Starts from the
/// sample mean and covariance; stops when an iteration raises ln L by less than 1e-12 × (1 +
/// |ln L|) or after `max_iterations`.
GaussianPopulation deconvolve_gaussian(const std::vector<Eigen::VectorXd>& points,
                                       const std::vector<Eigen::MatrixXd>& noise,
                                       int max_iterations = 20000);

/// The noise-free stand-in for one point (the file comment): μ + A (x − μ). Without noise (S = 0)
/// the point itself.
Eigen::VectorXd denoise(const GaussianPopulation& population, const Eigen::VectorXd& point,
                        const Eigen::MatrixXd& noise);

/// The symmetric positive semi-definite square root of a symmetric matrix (negative
/// eigenvalues, rounding's, taken as 0); with `inverse`, the pseudo-inverse's.
Eigen::MatrixXd symmetric_sqrt(const Eigen::MatrixXd& m, bool inverse = false);

}  // namespace shapesim
