// measure.hpp: the Moffat fitted to a star recovers the profile it was drawn from.
#include "shapesim/measure.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace shapesim;

namespace {

// A circular Moffat (FWHM w pixels, index beta, unit peak) about (x, y), each pixel the mean
// of 21 × 21 point values: closer to the pixel integral than the fit's own 5 × 5.
ImageArray moffat_image(int side, double x, double y, double w, double beta, double background) {
    const double alpha = w / (2.0 * std::sqrt(std::pow(2.0, 1.0 / beta) - 1.0));
    ImageArray image(side, side);
    constexpr int m = 21;
    for (int j = 0; j < side; ++j)
        for (int i = 0; i < side; ++i) {
            double sum = 0.0;
            for (int b = 0; b < m; ++b)
                for (int a = 0; a < m; ++a) {
                    const double dx = i + (a + 0.5) / m - 0.5 - x, dy = j + (b + 0.5) / m - 0.5 - y;
                    sum += std::pow(1.0 + (dx * dx + dy * dy) / (alpha * alpha), -beta);
                }
            image(j, i) = 1000.0 * sum / (m * m) + background;
        }
    return image;
}

}  // namespace

TEST(FitMoffat, RecoversTheProfileOfANoiseFreeStar) {
    for (const double w : {2.2, 3.5, 6.0}) {
        const int side = 2 * int(std::ceil(3.0 * w)) + 1;
        const double x = side / 2 + 0.3, y = side / 2 - 0.2;
        const ImageArray image = moffat_image(side, x, y, w, 3.0, 0.5);
        MaskArray use = MaskArray::Ones(side, side);
        use(1, 1) = 0;
        // Started from a centroid off by a pixel and a FWHM 30% wide, as a detection gives.
        const MoffatFit fit = fit_moffat(image, use, x + 0.8, y - 0.6, 1.3 * w);
        ASSERT_TRUE(fit.converged) << w;
        EXPECT_NEAR(fit.fwhm / w, 1.0, 2e-4) << w;
        EXPECT_NEAR(fit.beta, 3.0, 0.02) << w;
        EXPECT_NEAR(fit.x, x, 1e-3);
        EXPECT_NEAR(fit.y, y, 1e-3);
        EXPECT_NEAR(fit.background, 0.5, 0.05);
    }
}

TEST(FitMoffat, TooFewPixelsIsNoFit) {
    const ImageArray image = ImageArray::Ones(2, 2);
    const MaskArray use = MaskArray::Ones(2, 2);
    EXPECT_FALSE(fit_moffat(image, use, 0.5, 0.5, 2.0).converged);
}
