// Stress tests (`make stress`): orders far past the paper's, extreme β, NaN-riddled and large
// inputs. Slower than unit tests; the same closed-form checks, pushed to the edges.
#include "shapesim/decompose.hpp"
#include "shapesim/error.hpp"
#include "shapesim/lsq.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/polar.hpp"
#include "shapesim/render.hpp"
#include "../unit/test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <random>

using namespace shapesim;

// n_max 101: the polar ↔ Cartesian round trip stays exact and a flux-complete render sums to
// the closed-form flux.
TEST(Stress, OrderPast100) {
    const int n_max = 101;
    const ShapeletModel model = test::random_model(n_max, 1.5, 60.4, 59.7, 1);
    const ShapeletModel back = to_polar(to_cartesian(model));
    double err = 0.0;
    for (size_t k = 0; k < model.coeffs.size(); ++k)
        err = std::max(err, std::abs(back.coeffs[k] - model.coeffs[k]));
    EXPECT_LT(err, 1e-11);
    const ImageArray image = render_stamp(model, 120, 120);  // extent β√102 = 15 px
    ASSERT_TRUE(image.allFinite());
    EXPECT_NEAR(image.sum(), flux(model), 1e-11 * std::abs(flux(model)));
}

// β far below a pixel: the model is unresolved, yet pixel integration is exact, so the flux
// lands in the pixels in full; β far above the stamp: each pixel is its centre value to the
// curvature term, (1/24)∇²f ~ n_max f/β² ≈ 4e-5 of the peak.
TEST(Stress, ExtremeBeta) {
    for (double beta : {0.02, 0.1, 0.3}) {
        const ShapeletModel model = test::random_model(10, beta, 8.3, 7.6, 2);
        const ImageArray image = render_stamp(model, 16, 16);
        ASSERT_TRUE(image.allFinite()) << beta;
        EXPECT_NEAR(image.sum(), flux(model), 1e-12 * std::abs(flux(model)) + 1e-15) << beta;
    }
    const ShapeletModel wide = test::random_model(10, 500.0, 8.3, 7.6, 3);
    const ImageArray image = render_stamp(wide, 16, 16);
    ASSERT_TRUE(image.allFinite());
    double worst = 0.0;
    for (int j = 0; j < 16; ++j)
        for (int i = 0; i < 16; ++i)
            worst = std::max(worst, std::abs(image(j, i) - evaluate(wide, i + 1, j + 1)));
    EXPECT_LT(worst, 1e-4 * image.abs().maxCoeff());
}

// Half the pixels NaN at random: the fit uses the rest and recovers the model; all NaN is a
// clear error, not a crash.
TEST(Stress, NanRiddledStamp) {
    const ShapeletModel truth = test::random_model(8, 2.5, 32.2, 31.9, 4);
    ImageArray image = render_stamp(truth, 64, 64);
    std::mt19937_64 engine(5);
    for (long p = 0; p < image.size(); ++p)
        if (engine() % 2) image.data()[p] = std::nan("");
    const ImageArray weight = ImageArray::Ones(64, 64);
    const ShapeletFit fit = fit_shapelets(image, weight, nullptr, truth.x, truth.y, 2.5, 8);
    const Eigen::VectorXd a = real_parameters(fit.model), t = real_parameters(truth);
    EXPECT_LT((a - t).cwiseAbs().maxCoeff(), 1e-9 * t.cwiseAbs().maxCoeff());
    image.setConstant(std::nan(""));
    EXPECT_THROW(fit_shapelets(image, weight, nullptr, truth.x, truth.y, 2.5, 8), Error);
}

// A large image (8192², 512 MB): windows at the corners and edges clip correctly and the
// untouched pixels stay zero.
TEST(Stress, LargeImageWindows) {
    const int side = 8192;
    ImageArray image = ImageArray::Zero(side, side);
    const ShapeletModel model = test::random_model(15, 3.0, 0, 0, 6);
    for (double x : {1.0, side / 2.0, double(side)})
        for (double y : {1.0, double(side)}) {
            CartesianModel cart = to_cartesian(model);
            cart.x = x;
            cart.y = y;
            add_to_image(cart, image, PixelWindow{int(x) - 40, int(y) - 40, 81, 81});
        }
    ASSERT_TRUE(image.allFinite());
    EXPECT_EQ(image.block(100, 100, side - 200, side / 2 - 200).abs().maxCoeff(), 0.0);
    EXPECT_NE(image(0, 0), 0.0);
    EXPECT_NE(image(side - 1, side - 1), 0.0);
}

// The decompose grid of the unit tests with five times the models (480 stamps): flux pulls
// unbiased to |μ| < 0.1 (+2 standard errors) at S/N ≥ 100, honest (rms ≈ 1) at every S/N;
// the S/N-10 mean (truncation of orders the noise hides) reported.
TEST(Stress, DecomposeFluxPulls) {
    const test::DecomposeGrid g = test::decompose_grid(20);
    for (double snr : {10.0, 100.0, 1000.0}) {
        const test::MeanRms p = test::mean_rms(g.pull, g.snr, [&](double s) { return s == snr; });
        std::cout << "  [measured] S/N " << snr << ": flux pull mean " << p.mean << " ± "
                  << p.error << ", rms " << p.rms << " (" << p.n << " stamps)\n";
        EXPECT_GT(p.rms, 0.8) << "S/N " << snr;
        EXPECT_LT(p.rms, 1.5) << "S/N " << snr;
    }
    const test::MeanRms bright = test::mean_rms(g.pull, g.snr, [](double s) { return s >= 100.0; });
    std::cout << "  [measured] S/N ≥ 100: flux pull mean " << bright.mean << " ± " << bright.error
              << "; fitted n_max above the truth by at most " << g.max_excess << "\n";
    EXPECT_LT(std::abs(bright.mean), 0.1 + 2.0 * bright.error);
    EXPECT_LE(g.max_excess, 2);
}
