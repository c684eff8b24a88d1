// A population seen through noise, and the population without it (issue 17: the colours of
// jointly fitted galaxies).
//
// Each measurement x_i = v_i + ε_i: the true value v_i ~ N(μ, V), the noise ε_i ~ N(0, S_i)
// with S_i known and different for each point. The sample covariance of the x_i is V plus
// the mean S_i; a simulation that copies x_i and adds its own noise again has V + 2 S̄.
//
//  - deconvolve_gaussian: μ and V by maximum likelihood, Π_i N(x_i; μ, V + S_i), with the EM
//    iteration of "extreme deconvolution" for one Gaussian (Bovy, Hogg & Roweis 2011, Ann.
//    Appl. Stat. 5, 1657, §2):  b_i = μ + V T_i⁻¹ (x_i − μ),  B_i = V − V T_i⁻¹ V,
//    T_i = V + S_i;  μ ← mean b_i,  V ← mean[(b_i − μ)(b_i − μ)ᵀ + B_i].  Each step raises
//    the likelihood; a noisy point pulls on μ and V only as far as its S_i lets it.
//  - denoise: moves x_i by the least-displacement (optimal-transport) linear map from
//    N(μ, V + S_i) to N(μ, V): x' = μ + A_i (x_i − μ), A_i symmetric with A_i T_i A_i = V,
//    A_i = T_i^{−1/2} (T_i^{1/2} V T_i^{1/2})^{1/2} T_i^{−1/2}. Each point then scatters about
//    μ as the population itself does (variance matching, the "constrained Bayes" of Louis
//    1984, J. Am. Stat. Assoc. 79, 393): a precise point barely moves, a noisy one is drawn
//    towards μ, and noise added back gives the measured spread, not twice the noise.
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

/// The noise-free stand-in for one point (see above): μ + A (x − μ). Without noise (S = 0)
/// the point itself.
Eigen::VectorXd denoise(const GaussianPopulation& population, const Eigen::VectorXd& point,
                        const Eigen::MatrixXd& noise);

/// The symmetric positive semi-definite square root of a symmetric matrix (negative
/// eigenvalues, rounding's, taken as 0); with `inverse`, the pseudo-inverse's.
Eigen::MatrixXd symmetric_sqrt(const Eigen::MatrixXd& m, bool inverse = false);

}  // namespace shapesim
