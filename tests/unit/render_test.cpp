// The separable pixel-integrated renderer against GalSim's exact reference stamps and against
// brute-force 2D integration of the polar formula.
#include "shapesim/render.hpp"

#include "shapesim/polar.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace shapesim;

// Every reference stamp (GalSim real-space drawing, 1e-10 relative) to 1e-9 of its peak
// (the README's suggested tolerance; we reach ~2e-15).
TEST(Render, ReproducesGalSimReferenceStamps) {
    const auto& refs = test::reference_models();
    ASSERT_EQ(refs.size(), 24u);
    for (const auto& r : refs) {
        const ImageArray image = render_stamp(r.model, r.nx, r.ny);
        ASSERT_EQ(image.rows(), r.stamp.rows());
        ASSERT_EQ(image.cols(), r.stamp.cols());
        const double peak = r.stamp.abs().maxCoeff();
        EXPECT_LT((image - r.stamp).abs().maxCoeff(), 1e-9 * peak) << r.id;
    }
}

// Pixel-integrated polar model equals brute-force 2D Gauss–Legendre integration of the
// paper's formula (polar evaluate) over each pixel, to 1e-12 of the peak.
TEST(Render, PixelIntegrationMatchesBruteForce) {
    const ShapeletModel model = test::random_model(10, 1.3, 4.6, 5.2, 3);
    const ImageArray image = render_stamp(model, 9, 10);
    std::vector<double> nodes, weights;
    test::gauss_legendre(16, nodes, weights);
    double worst = 0.0;
    for (int j = 0; j < image.rows(); ++j)
        for (int i = 0; i < image.cols(); ++i) {
            double sum = 0.0;
            for (size_t a = 0; a < nodes.size(); ++a)
                for (size_t b = 0; b < nodes.size(); ++b)
                    sum += 0.25 * weights[a] * weights[b] *
                           evaluate(model, i + 1 + 0.5 * nodes[a], j + 1 + 0.5 * nodes[b]);
            worst = std::max(worst, std::abs(sum - image(j, i)));
        }
    EXPECT_LT(worst, 1e-12 * image.abs().maxCoeff());
}

// Rendering into a window of a larger image equals the stamp, shifted, and clipping at the
// image edge keeps exactly the overlapping pixels.
TEST(Render, WindowIntoLargerImageAndClipping) {
    const ShapeletModel model = test::random_model(6, 2.0, 20.25, 30.75, 5);
    const CartesianModel cart = to_cartesian(model);
    ImageArray big = ImageArray::Zero(50, 40);
    add_to_image(cart, big, PixelWindow{10, 20, 21, 21});
    CartesianModel local = cart;
    local.x -= 10;
    local.y -= 20;
    const ImageArray stamp = render_stamp(local, 21, 21);
    EXPECT_EQ((big.block(20, 10, 21, 21) - stamp).abs().maxCoeff(), 0.0);
    big.block(20, 10, 21, 21).setZero();
    EXPECT_EQ(big.abs().maxCoeff(), 0.0);  // nothing written outside the window

    ImageArray edge = ImageArray::Zero(25, 25);
    add_to_image(cart, edge, PixelWindow{10, 20, 21, 21});  // rows 20..24 only
    EXPECT_EQ((edge.block(20, 10, 5, 15) - stamp.block(0, 0, 5, 15)).abs().maxCoeff(), 0.0);
    ImageArray outside = ImageArray::Zero(5, 5);
    add_to_image(cart, outside, PixelWindow{10, 20, 21, 21});
    EXPECT_EQ(outside.abs().maxCoeff(), 0.0);
}

// A flux-complete stamp sums to the model flux 2√π β Σ a_{n,0} (n even).
TEST(Render, StampSumIsFlux) {
    const ShapeletModel model = test::random_model(8, 1.5, 30.3, 29.6, 9);
    double flux = 0.0;
    for (int n = 0; n <= 8; n += 2) flux += model.at(n, 0).real();
    flux *= 2 * std::sqrt(M_PI) * model.beta_pix;
    EXPECT_NEAR(render_stamp(model, 60, 60).sum(), flux, 1e-13 * std::abs(flux));
}
