// The exact circular aperture (exact_aperture.hpp): pixel areas against a brute-force
// integration, sums against libsep's sep_sum_circle on random images, centres and radii
// (circles cut by the edges, radii below a pixel, centres on pixel centres and corners).
#include "shapesim/exact_aperture.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

using namespace shapesim;

namespace {

// ∫ f over [cuts.front(), cuts.back()], f smooth between consecutive cuts: test_support's
// 20-point Gauss–Legendre on 8 panels of each piece.
template <class F>
double integrate_pieces(F f, std::vector<double> cuts) {
    std::sort(cuts.begin(), cuts.end());
    double area = 0.0;
    for (std::size_t k = 0; k + 1 < cuts.size(); ++k)
        area += test::integrate(f, cuts[k], cuts[k + 1], 8);
    return area;
}

// The area of [x0, x1] × [y0, y1] inside the circle by quadrature, independently of the corner
// areas: with t = r sin θ the column height min(y1, r cos θ) − max(y0, −r cos θ) times
// r cos θ is smooth between the angles where r cos θ meets |y0| or |y1|.
double overlap_by_quadrature(double x0, double y0, double x1, double y1, double r) {
    auto theta = [&](double t) { return std::asin(std::clamp(t / r, -1.0, 1.0)); };
    const double lo = theta(x0), hi = theta(x1);
    std::vector<double> cuts{lo, hi};
    for (double y : {y0, y1})
        if (std::abs(y) < r)
            for (double s : {-1.0, 1.0}) {
                const double c = s * std::acos(std::abs(y) / r);
                if (c > lo && c < hi) cuts.push_back(c);
            }
    auto f = [&](double th) {
        const double height = r * std::cos(th);
        return std::max(0.0, std::min(y1, height) - std::max(y0, -height)) * r * std::cos(th);
    };
    return integrate_pieces(f, cuts);
}

// A w × h image (sides 1 … 60) of signed values over many decades and some zeros (float
// rounding and cancellation matter), with Σ|v|.
struct RandomImage {
    int w, h;
    std::vector<double> data;
    double magnitude = 0.0;
};

RandomImage random_image(std::mt19937_64& rng) {
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    RandomImage im;
    im.w = 1 + int(unit(rng) * 60);
    im.h = 1 + int(unit(rng) * 60);
    im.data.resize(std::size_t(im.w) * std::size_t(im.h));
    for (double& v : im.data) {
        v = unit(rng) < 0.1 ? 0.0 : (unit(rng) - 0.3) * std::pow(10.0, 6.0 * unit(rng) - 3.0);
        im.magnitude += std::abs(v);
    }
    return im;
}

// The k-th centre on it: inside or up to 5 px outside; some on pixel centres, edges, corners.
void random_centre(std::mt19937_64& rng, int k, const RandomImage& im, double& x, double& y) {
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    x = -5.0 + (im.w + 10.0) * unit(rng);
    y = -5.0 + (im.h + 10.0) * unit(rng);
    if (k % 4 == 1) x = std::round(x);
    if (k % 4 == 2) y = std::round(y * 2.0) / 2.0;
    if (k % 8 == 3) x = std::round(x) + 0.5, y = std::round(y);
}

}  // namespace

TEST(ExactAperture, OverlapIsTheAreaInside) {
    EXPECT_NEAR(circle_overlap(-0.5, -0.5, 0.5, 0.5, 10.0), 1.0, 1e-15);
    EXPECT_NEAR(circle_overlap(-20.0, -20.0, 20.0, 20.0, 1.0), 3.1415926535897931, 1e-15);
    EXPECT_EQ(circle_overlap(5.0, 5.0, 6.0, 6.0, 1.0), 0.0);
    EXPECT_EQ(circle_overlap(-1.0, -1.0, 1.0, 1.0, 0.0), 0.0);
    // A quarter of the unit square's corner cut by the unit circle: π/4 − (its complement).
    EXPECT_NEAR(circle_overlap(0.0, 0.0, 1.0, 1.0, 1.0), 0.78539816339744831, 1e-15);
}

// Pixels, and wider rectangles, anywhere about circles from 0.05 to 60 pixels: the area to
// 2e-15 (1 + r²) of a pixel, the rounding of the corner areas (~r²) it is a difference of; the
// quadrature's own error is ~1e-16.
TEST(ExactAperture, OverlapMatchesQuadrature) {
    std::mt19937_64 rng(20261128);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    double worst = 0.0;
    for (int k = 0; k < 20000; ++k) {
        const double r = 0.05 + 60.0 * unit(rng) * unit(rng);
        // Lower-left corners near the edge (most of the cases an aperture meets) or anywhere.
        const double angle = 6.283185307179586 * unit(rng);
        const double rho = k % 3 == 0 ? (r + 2.0) * unit(rng) : r + 1.5 * (unit(rng) - 0.5);
        double x0 = rho * std::cos(angle) - 0.5, y0 = rho * std::sin(angle) - 0.5;
        if (k % 7 == 0) x0 = std::round(x0);  // lines through the centre
        if (k % 11 == 0) y0 = -0.5;           // a pixel centred on the centre's row
        const double wx = k % 5 == 0 ? 3.0 * unit(rng) : 1.0, wy = k % 5 == 0 ? 0.2 : 1.0;
        const double got = circle_overlap(x0, y0, x0 + wx, y0 + wy, r);
        const double want = overlap_by_quadrature(x0, y0, x0 + wx, y0 + wy, r);
        worst = std::max(worst, std::abs(got - want) / (1.0 + r * r));
        ASSERT_NEAR(got, want, 2e-15 * (1.0 + r * r)) << "r " << r << " box " << x0 << " " << y0 << " + " << wx
                                      << " × " << wy;
    }
    RecordProperty("worst_error_over_1_plus_r2", std::to_string(worst));
}

TEST(ExactAperture, SumsAsSepDoes) {
    std::mt19937_64 rng(20261127);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    int cases = 0;
    for (int image = 0; image < 40; ++image) {
        RandomImage im = random_image(rng);
        for (int k = 0; k < 400; ++k) {
            double x, y;
            random_centre(rng, k, im, x, y);
            const double r = k % 5 == 0 ? 1.5 * unit(rng)
                                        : (k % 5 == 1 ? std::round(8.0 * unit(rng)) / 2.0
                                                      : 0.05 + 40.0 * unit(rng) * unit(rng));
            if (!(r > 0.0)) continue;
            // Each pixel's area as OverlapMatchesQuadrature holds it (sep's to ~r ε).
            ASSERT_NEAR(sum_circle(im.data.data(), im.w, im.h, x, y, r),
                        test::sep_circle_sum(im.data, im.w, im.h, x, y, r),
                        2e-15 * (1.0 + r * r) * im.magnitude)
                << "w " << im.w << " h " << im.h << " x " << x << " y " << y << " r " << r;
            ++cases;
        }
    }
    EXPECT_GT(cases, 10000);
}

// The weights of one walk applied to several images give each image's own sum.
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
        visit_circle_rows(w, h, x, y, r, [&](int j, int begin, int end, const double* weights) {
            for (int i = begin; i < end; ++i) {
                sa += sep_term(a[std::size_t(j * w + i)], weights[i - begin]);
                sb += sep_term(b[std::size_t(j * w + i)], weights[i - begin]);
            }
        });
        EXPECT_EQ(sa, sum_circle(a.data(), w, h, x, y, r));
        EXPECT_EQ(sb, sum_circle(b.data(), w, h, x, y, r));
        EXPECT_NEAR(sa, test::sep_circle_sum(a, w, h, x, y, r), 1e-12 * w * h);
    }
}

namespace {

// The area of [x0, x1] × [y0, y1] inside the ellipse (semi-axes a along θ, b) by quadrature:
// with x = e_x sin φ (e_x the ellipse's half-width) the height of the ellipse's column inside
// [y0, y1] is smooth between the angles where the ellipse's edge meets y0 or y1.
double ellipse_by_quadrature(double x0, double y0, double x1, double y1, double a, double b,
                             double theta) {
    const double c = std::cos(theta), s = std::sin(theta);
    // cxx x² + cxy x y + cyy y² ≤ 1
    const double cxx = c * c / (a * a) + s * s / (b * b), cyy = s * s / (a * a) + c * c / (b * b),
                 cxy = 2.0 * c * s * (1.0 / (a * a) - 1.0 / (b * b));
    const double ex = std::sqrt(a * a * c * c + b * b * s * s);
    auto phi = [&](double x) { return std::asin(std::clamp(x / ex, -1.0, 1.0)); };
    const double lo = phi(x0), hi = phi(x1);
    std::vector<double> cuts{lo, hi};
    for (double y : {y0, y1}) {  // where the edge meets the line y: cxx x² + cxy y x + … = 1
        const double qa = cxx, qb = cxy * y, qc = cyy * y * y - 1.0;
        const double disc = qb * qb - 4.0 * qa * qc;
        if (disc <= 0.0) continue;
        for (double sgn : {-1.0, 1.0}) {
            const double p = phi((-qb + sgn * std::sqrt(disc)) / (2.0 * qa));
            if (p > lo && p < hi) cuts.push_back(p);
        }
    }
    auto f = [&](double ph) {
        const double x = ex * std::sin(ph), root = std::cos(ph);  // √(1 − x²/e_x²)
        // y± = (−cxy x ± √D)/(2 cyy), √D = 2 √cyy · root
        const double mid = -cxy * x / (2.0 * cyy), half = root / std::sqrt(cyy);
        const double height = std::max(0.0, std::min(y1, mid + half) - std::max(y0, mid - half));
        return height * ex * std::cos(ph);
    };
    return integrate_pieces(f, cuts);
}

}  // namespace

TEST(ExactAperture, EllipseOverlapIsTheAreaInside) {
    const double pi = 3.141592653589793;
    // The circle inscribed in a pixel (tangent to all four sides), and inside one side only.
    EXPECT_NEAR(ellipse_overlap(-0.5, -0.5, 0.5, 0.5, 0.5, 0.5, 0.3), pi / 4, 1e-15);
    EXPECT_NEAR(ellipse_overlap(-0.3, -0.5, 0.7, 0.5, 0.3, 0.2, 0.0), pi * 0.06, 1e-15);
    EXPECT_NEAR(ellipse_overlap(-0.5, -0.5, 0.5, 0.5, 0.5, 0.1, 0.0), pi * 0.05, 1e-15);
    // A pixel well inside, one outside, one touching the ellipse's tip from outside.
    EXPECT_NEAR(ellipse_overlap(-0.5, -0.5, 0.5, 0.5, 10.0, 3.0, 1.0), 1.0, 1e-14);
    EXPECT_EQ(ellipse_overlap(20.0, 20.0, 21.0, 21.0, 10.0, 3.0, 1.0), 0.0);
    EXPECT_NEAR(ellipse_overlap(10.0, -0.5, 11.0, 0.5, 10.0, 3.0, 0.0), 0.0, 1e-15);
    // Half and a quarter of the whole.
    EXPECT_NEAR(ellipse_overlap(0.0, -50.0, 50.0, 50.0, 10.0, 3.0, 0.0), pi * 15.0, 1e-12);
    EXPECT_NEAR(ellipse_overlap(0.0, 0.0, 50.0, 50.0, 10.0, 3.0, 0.0), pi * 7.5, 1e-12);
    EXPECT_EQ(ellipse_overlap(-1.0, -1.0, 1.0, 1.0, 0.0, 1.0, 0.0), 0.0);
    // Corners on the edge (to rounding, either side of it): the circle through a pixel's four
    // corners holds it whole, and beyond two of them a segment of a quarter of the circle.
    const double r = std::sqrt(0.5);
    for (double theta : {0.0, 0.1, 0.7, 1.5707963267948966, 2.5, -1.0}) {
        EXPECT_NEAR(ellipse_overlap(-0.5, -0.5, 0.5, 0.5, r, r, theta), 1.0, 1e-14) << theta;
        EXPECT_NEAR(ellipse_overlap(0.5, -0.5, 1.5, 0.5, r, r, theta), 0.25 * (pi / 2 - 1.0),
                    1e-14)
            << theta;
        EXPECT_NEAR(ellipse_overlap(-0.5, 0.5, 0.5, 1.5, r, r, theta), 0.25 * (pi / 2 - 1.0),
                    1e-14)
            << theta;
    }
    // Pixels whose corner lies on the ellipse (to rounding) from outside: the exit from one edge
    // and the entry into the next meet there, and the arc between them is empty, not the whole
    // ellipse (found by a search; the overlap is ~0).
    EXPECT_NEAR(ellipse_overlap(0.5, -19.5, 1.5, -18.5, 18.818572845442304, 15.548548959139572,
                                1.3240355914752051),
                0.0, 1e-12);
    EXPECT_NEAR(ellipse_overlap(10.5, -14.5, 11.5, -13.5, 20.404613317241918, 16.545409405603102,
                                0.21365011389717337),
                0.0, 1e-12);
}

// Pixels about ellipses from 0.05 to 50 pixels, axis ratios to 6, every angle: the area to
// 4e-15 (1 + a²), as the circle's.
TEST(ExactAperture, EllipseOverlapMatchesQuadrature) {
    std::mt19937_64 rng(20261129);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    double worst = 0.0;
    for (int k = 0; k < 20000; ++k) {
        const double a = 0.05 + 50.0 * unit(rng) * unit(rng);
        const double b = a / (1.0 + 5.0 * unit(rng) * unit(rng));
        double theta = 3.141592653589793 * unit(rng);
        if (k % 9 == 0) theta = 0.0;
        if (k % 9 == 1) theta = 1.5707963267948966;
        // Pixels about the edge (most of those an aperture meets) or anywhere.
        const double angle = 6.283185307179586 * unit(rng);
        const double along = k % 3 == 0 ? unit(rng) : 1.0 + 0.3 * (unit(rng) - 0.5);
        const double ex = a * std::cos(angle), ey = b * std::sin(angle);
        double x0 = along * (ex * std::cos(theta) - ey * std::sin(theta)) - 0.5,
               y0 = along * (ex * std::sin(theta) + ey * std::cos(theta)) - 0.5;
        if (k % 7 == 0) x0 = -0.5, y0 = std::round(y0) - 0.5;  // the centre's column
        const double got = ellipse_overlap(x0, y0, x0 + 1.0, y0 + 1.0, a, b, theta);
        const double want = ellipse_by_quadrature(x0, y0, x0 + 1.0, y0 + 1.0, a, b, theta);
        worst = std::max(worst, std::abs(got - want) / (1.0 + a * a));
        ASSERT_NEAR(got, want, 4e-15 * (1.0 + a * a))
            << "a " << a << " b " << b << " θ " << theta << " pixel " << x0 << " " << y0;
    }
    RecordProperty("worst_error_over_1_plus_a2", std::to_string(worst));
}

TEST(ExactAperture, EllipseSumsAsSepDoes) {
    std::mt19937_64 rng(20261130);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    int cases = 0;
    for (int image = 0; image < 30; ++image) {
        RandomImage im = random_image(rng);
        for (int k = 0; k < 300; ++k) {
            double x, y;
            random_centre(rng, k, im, x, y);
            const double a =
                k % 5 == 0 ? 0.05 + 1.5 * unit(rng) : 0.05 + 30.0 * unit(rng) * unit(rng);
            const double b = a / (1.0 + 4.0 * unit(rng));
            const double theta = 3.14 * unit(rng) - 1.57;  // sep takes |θ| ≤ π/2
            ASSERT_NEAR(sum_ellipse(im.data.data(), im.w, im.h, x, y, a, b, theta),
                        test::sep_ellipse_sum(im.data, im.w, im.h, x, y, a, b, theta),
                        4e-15 * (1.0 + a * a) * im.magnitude)
                << "w " << im.w << " h " << im.h << " x " << x << " y " << y << " a " << a
                << " b " << b << " θ " << theta;
            ++cases;
        }
    }
    EXPECT_GT(cases, 8000);
}

// Apertures that are not there (non-positive or non-finite radii, axes, angles or centres, as
// a failed fit can hand on) sum to 0 rather than cast a NaN to a pixel index.
TEST(ExactAperture, UndefinedAperturesSumToZero) {
    const double nan = std::numeric_limits<double>::quiet_NaN(),
                 inf = std::numeric_limits<double>::infinity();
    const std::vector<double> data(100, 1.0);
    EXPECT_EQ(sum_circle(data.data(), 10, 10, nan, 5.0, 2.0), 0.0);
    EXPECT_EQ(sum_circle(data.data(), 10, 10, 5.0, inf, 2.0), 0.0);
    EXPECT_EQ(sum_circle(data.data(), 10, 10, 5.0, 5.0, inf), 0.0);
    EXPECT_EQ(sum_circle(data.data(), 10, 10, 5.0, 5.0, -1.0), 0.0);
    EXPECT_EQ(sum_ellipse(data.data(), 10, 10, 5.0, 5.0, 2.0, 1.0, nan), 0.0);
    EXPECT_EQ(sum_ellipse(data.data(), 10, 10, 5.0, 5.0, 2.0, inf, 0.0), 0.0);
    EXPECT_EQ(sum_ellipse(data.data(), 10, 10, nan, 5.0, 2.0, 1.0, 0.0), 0.0);
    EXPECT_EQ(sum_ellipse(data.data(), 10, 10, 5.0, 5.0, 0.0, 1.0, 0.0), 0.0);
    // And a defined one on the same image: the area.
    EXPECT_NEAR(sum_circle(data.data(), 10, 10, 4.5, 4.5, 2.0), 4.0 * std::atan(1.0) * 4.0, 1e-13);
    EXPECT_NEAR(sum_ellipse(data.data(), 10, 10, 4.5, 4.5, 3.0, 1.5, 0.4),
                4.0 * std::atan(1.0) * 4.5, 1e-13);
}
