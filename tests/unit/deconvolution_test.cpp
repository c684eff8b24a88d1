// deconvolution.hpp: a Gaussian population behind heteroscedastic noise, and the points moved
// to scatter as the population does.
#include "shapesim/deconvolution.hpp"

#include "shapesim/error.hpp"
#include "shapesim/rng.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace shapesim;

namespace {

struct NoisySample {
    std::vector<Eigen::VectorXd> truth, points;
    std::vector<Eigen::MatrixXd> noise;
};

// n draws of N(mean, cov) seen through noise whose σ runs from 0.3 to 3 times the population's
// (correlated between the axes for every third point), as faint galaxies' colours are.
NoisySample noisy_sample(int n, const Eigen::Vector2d& mean, const Eigen::Matrix2d& cov,
                         std::uint64_t seed) {
    RandomStream stream(seed, 0, "deconvolution test");
    const Eigen::Matrix2d l = cov.llt().matrixL();
    NoisySample s;
    for (int i = 0; i < n; ++i) {
        const Eigen::Vector2d v = mean + l * Eigen::Vector2d(stream.gaussian(), stream.gaussian());
        const double scale = 0.3 + 2.7 * stream.uniform();
        Eigen::Matrix2d noise = scale * scale * cov.diagonal().asDiagonal();
        if (i % 3 == 0) noise(0, 1) = noise(1, 0) = 0.5 * std::sqrt(noise(0, 0) * noise(1, 1));
        const Eigen::Matrix2d ln = noise.llt().matrixL();
        s.truth.push_back(v);
        s.points.push_back(v + ln * Eigen::Vector2d(stream.gaussian(), stream.gaussian()));
        s.noise.push_back(noise);
    }
    return s;
}

Eigen::MatrixXd sample_covariance(const std::vector<Eigen::VectorXd>& x) {
    Eigen::VectorXd m = Eigen::VectorXd::Zero(x.front().size());
    for (const auto& v : x) m += v / double(x.size());
    Eigen::MatrixXd c = Eigen::MatrixXd::Zero(m.size(), m.size());
    for (const auto& v : x) c += (v - m) * (v - m).transpose() / double(x.size() - 1);
    return c;
}

const Eigen::Vector2d kMean(0.4, -1.1);
Eigen::Matrix2d population_cov() {
    Eigen::Matrix2d c;
    c << 0.040, 0.024, 0.024, 0.025;
    return c;
}

}  // namespace

TEST(Deconvolution, RecoversThePopulationBehindTheNoise) {
    const NoisySample s = noisy_sample(6000, kMean, population_cov(), 1);
    const GaussianPopulation pop = deconvolve_gaussian(s.points, s.noise);
    EXPECT_TRUE(pop.converged);
    // Standard errors for n = 6000 with noise up to 3σ: a few ×1e-3 on the mean, ≲ 3e-3 on V.
    EXPECT_NEAR(pop.mean(0), kMean(0), 0.012);
    EXPECT_NEAR(pop.mean(1), kMean(1), 0.010);
    const Eigen::Matrix2d v = population_cov();
    for (int i = 0; i < 2; ++i)
        for (int j = 0; j < 2; ++j) EXPECT_NEAR(pop.covariance(i, j), v(i, j), 0.006) << i << j;
    // The measured points' own covariance is V + mean S, about four times V: the test can tell.
    const Eigen::MatrixXd naive = sample_covariance(s.points);
    EXPECT_GT(naive(0, 0), 3.0 * v(0, 0));
}

TEST(Deconvolution, LikelihoodNeverFalls) {
    const NoisySample s = noisy_sample(300, kMean, population_cov(), 2);
    double previous = -INFINITY;
    for (int k = 1; k <= 30; ++k) {
        const GaussianPopulation pop = deconvolve_gaussian(s.points, s.noise, k);
        EXPECT_GE(pop.log_likelihood, previous - 1e-9 * std::abs(previous)) << k;
        previous = pop.log_likelihood;
    }
}

TEST(Deconvolution, DenoisedPointsScatterAsThePopulationAndNoiseAddsBackTheData) {
    const NoisySample s = noisy_sample(6000, kMean, population_cov(), 3);
    const GaussianPopulation pop = deconvolve_gaussian(s.points, s.noise);
    std::vector<Eigen::VectorXd> denoised, renoised;
    RandomStream stream(3, 1, "renoise");
    for (std::size_t i = 0; i < s.points.size(); ++i) {
        denoised.push_back(denoise(pop, s.points[i], s.noise[i]));
        const Eigen::Matrix2d ln = Eigen::Matrix2d(s.noise[i]).llt().matrixL();
        renoised.push_back(denoised.back() + ln * Eigen::Vector2d(stream.gaussian(), stream.gaussian()));
    }
    const Eigen::MatrixXd c = sample_covariance(denoised), v = population_cov();
    for (int i = 0; i < 2; ++i)
        for (int j = 0; j < 2; ++j) EXPECT_NEAR(c(i, j), v(i, j), 0.006) << i << j;
    // A simulation of the denoised points has the data's spread; one of the points, twice the
    // noise (the problem this solves).
    const Eigen::MatrixXd data = sample_covariance(s.points), sim = sample_covariance(renoised);
    EXPECT_NEAR(sim(0, 0) / data(0, 0), 1.0, 0.06);
    EXPECT_NEAR(sim(1, 1) / data(1, 1), 1.0, 0.06);
    // Each denoised point stays nearer its truth than its measurement, on the whole.
    double before = 0.0, after = 0.0;
    for (std::size_t i = 0; i < s.points.size(); ++i) {
        before += (s.points[i] - s.truth[i]).squaredNorm();
        after += (denoised[i] - s.truth[i]).squaredNorm();
    }
    EXPECT_LT(after, 0.6 * before);
}

TEST(Deconvolution, MapIsExactTransportAndIdentityWithoutNoise) {
    GaussianPopulation pop;
    pop.mean = Eigen::Vector3d(1.0, 2.0, -0.5);
    Eigen::Matrix3d r;
    r << 0.3, 0.1, -0.2, 0.0, 0.5, 0.1, 0.2, -0.1, 0.4;
    pop.covariance = r * r.transpose();
    Eigen::Matrix3d q;
    q << 0.2, 0.05, 0.0, -0.1, 0.3, 0.2, 0.0, 0.1, 0.6;
    const Eigen::MatrixXd noise = q * q.transpose();
    // The map is linear: its matrix column by column, then A (V + S) A = V and A = Aᵀ.
    Eigen::Matrix3d a;
    for (int k = 0; k < 3; ++k)
        a.col(k) = denoise(pop, pop.mean + Eigen::Vector3d::Unit(k), noise) - pop.mean;
    EXPECT_LT((a * (pop.covariance + noise) * a - pop.covariance).norm(), 1e-12);
    EXPECT_LT((a - a.transpose()).norm(), 1e-12);
    const Eigen::Vector3d x(0.3, 0.7, 1.9);
    EXPECT_EQ(denoise(pop, x, Eigen::Matrix3d::Zero()), Eigen::VectorXd(x));
}

TEST(Deconvolution, BadInputIsAnError) {
    std::vector<Eigen::VectorXd> one{Eigen::Vector2d(1, 2)};
    std::vector<Eigen::MatrixXd> noise{Eigen::Matrix2d::Identity()};
    EXPECT_THROW(deconvolve_gaussian(one, noise), Error);
    std::vector<Eigen::VectorXd> two{Eigen::Vector2d(1, 2), Eigen::Vector2d(NAN, 0)};
    noise.push_back(Eigen::Matrix2d::Identity());
    EXPECT_THROW(deconvolve_gaussian(two, noise), Error);
    two[1] = Eigen::Vector3d(1, 2, 3);
    EXPECT_THROW(deconvolve_gaussian(two, noise), Error);
}
