// The exact circular aperture (exact_aperture.hpp) against libsep's sep_sum_circle: the same
// double, bit for bit, on random images, centres and radii, including circles cut by the edges,
// radii below a pixel and centres on pixel centres and corners.
#include "shapesim/exact_aperture.hpp"

#include <cstddef>  // sep.h uses size_t without including it
extern "C" {        // sep.h has no C++ guards
#include <sep.h>
}

#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <vector>

using namespace shapesim;

namespace {

double sep_circle(std::vector<double>& data, int w, int h, double x, double y, double r) {
    sep_image im{};
    im.data = data.data();
    im.dtype = SEP_TDOUBLE;
    im.w = w;
    im.h = h;
    im.noise_type = SEP_NOISE_NONE;
    double sum = 0.0, err = 0.0, area = 0.0;
    short flag = 0;
    EXPECT_EQ(sep_sum_circle(&im, x, y, r, 0, 0, 0, &sum, &err, &area, &flag), 0);
    return sum;
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

}  // namespace

TEST(ExactAperture, SumsAsSepDoesBitForBit) {
    std::mt19937_64 rng(20261127);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    int cases = 0, mismatches = 0;
    for (int image = 0; image < 40; ++image) {
        const int w = 1 + int(unit(rng) * 60), h = 1 + int(unit(rng) * 60);
        std::vector<double> data(std::size_t(w) * std::size_t(h));
        // Signed values over many decades, some zeros: float rounding and cancellation matter.
        for (double& v : data)
            v = unit(rng) < 0.1 ? 0.0 : (unit(rng) - 0.3) * std::pow(10.0, 6.0 * unit(rng) - 3.0);
        for (int k = 0; k < 400; ++k) {
            // Centres inside and up to 5 px outside; some on pixel centres, edges and corners.
            double x = -5.0 + (w + 10.0) * unit(rng), y = -5.0 + (h + 10.0) * unit(rng);
            if (k % 4 == 1) x = std::round(x);
            if (k % 4 == 2) y = std::round(y * 2.0) / 2.0;
            if (k % 8 == 3) x = std::round(x) + 0.5, y = std::round(y);
            const double r = k % 5 == 0 ? 1.5 * unit(rng)
                                        : (k % 5 == 1 ? std::round(8.0 * unit(rng)) / 2.0
                                                      : 0.05 + 40.0 * unit(rng) * unit(rng));
            if (!(r > 0.0)) continue;
            const double expected = sep_circle(data, w, h, x, y, r);
            const double got = sum_circle(data.data(), w, h, x, y, r);
            ++cases;
            if (!same_bits(expected, got)) {
                if (++mismatches <= 5)
                    ADD_FAILURE() << "w " << w << " h " << h << " x " << x << " y " << y << " r "
                                  << r << ": sep " << expected << ", ours " << got;
            }
        }
    }
    EXPECT_GT(cases, 10000);
    EXPECT_EQ(mismatches, 0);
}

// The weights of one walk applied to several images give each image's own sep sum.
TEST(ExactAperture, OneWalkWeighsSeveralImages) {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    const int w = 37, h = 29;
    std::vector<double> a(w * h), b(w * h);
    for (std::size_t k = 0; k < a.size(); ++k) {
        a[k] = unit(rng);
        b[k] = 1e3 * unit(rng);
    }
    for (int k = 0; k < 200; ++k) {
        const double x = 18.0 + 20.0 * unit(rng), y = 14.0 + 16.0 * unit(rng);
        const double r = 0.3 + 12.0 * (1.0 + unit(rng));
        double sa = 0.0, sb = 0.0;
        visit_circle(w, h, x, y, r, [&](int i, int j, double weight) {
            sa += sep_term(a[std::size_t(j * w + i)], weight);
            sb += sep_term(b[std::size_t(j * w + i)], weight);
        });
        EXPECT_TRUE(same_bits(sa, sep_circle(a, w, h, x, y, r)));
        EXPECT_TRUE(same_bits(sb, sep_circle(b, w, h, x, y, r)));
    }
}

TEST(ExactAperture, OverlapIsTheAreaInside) {
    EXPECT_DOUBLE_EQ(circle_overlap(-0.5, -0.5, 0.5, 0.5, 10.0), 1.0);
    EXPECT_DOUBLE_EQ(circle_overlap(-20.0, -20.0, 20.0, 20.0, 1.0), 3.1415926535897931);
    EXPECT_EQ(circle_overlap(5.0, 5.0, 6.0, 6.0, 1.0), 0.0);
    EXPECT_EQ(circle_overlap(-1.0, -1.0, 1.0, 1.0, 0.0), 0.0);
}
