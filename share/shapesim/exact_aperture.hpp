// Exact apertures (as sep_sum_circle and sep_sum_ellipse with subpix 0, no mask, no noise,
// and photutils' "exact" method): each pixel weighted by the area of it inside the circle or
// ellipse. One walk over a circle's pixels can weigh several images at once (the asymmetry's
// three sums).
//
// The circle's areas come from the area of the circle in the rectangle [0, x] × [0, y], which
// needs √(r² − x²) and asin(x/r) of each grid line, not of each pixel: the transcendental
// functions are evaluated once per row and column of the box (2 (2r + 4) of them), instead of
// sep's asin and sin in up to four quadrant pieces of each of the ~8r pixels the edge crosses.
// The ellipse's (exact_aperture.cpp) likewise need one acos per grid line. The areas equal
// sep's to rounding (tests/unit/exact_aperture_test.cpp: ≤ 4e-15 (1 + a²) of a pixel against
// quadratures, and the sums against sep itself); the pixels' order and each value's rounding to
// float (sep's PIXTYPE) are sep's.
#pragma once

#include "shapesim/constants.hpp"
#include "shapesim/lane_math.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace shapesim {

/// A grid line at signed distance t from the circle's centre, as the corner areas need it.
struct CircleLine {
    double sign;  ///< of t
    double a;     ///< |t|, at most r
    double h;     ///< √(r² − a²): the circle's half-chord along the line
    double g;     ///< asin(a / r)
};

inline CircleLine circle_line(double t, double r) {
    const double a = std::min(std::abs(t), r);
    return {t < 0.0 ? -1.0 : 1.0, a, std::sqrt((r - a) * (r + a)), lane::asin(a / r)};
}

/// out[n] = circle_line((first + n − ½) − x, r) for n < count: the lines of a box, four at a
/// time in lanes (the same bits).
void circle_lines(int first, int count, double x, double r, CircleLine* out);

/// The area of the circle of radius r about the origin inside [0, x] × [0, y], signed (odd in
/// x and in y), for the lines x and y. A corner inside the circle bounds a rectangle inside it;
/// otherwise the area is x_c·y plus ∫ √(r² − t²) dt from x_c = √(r² − y²) to x, which
/// simplifies to the form below.
inline double corner_area(const CircleLine& x, const CircleLine& y, double r) {
    const double r2 = r * r;
    const double q = x.a * x.a + y.a * y.a <= r2
                         ? x.a * y.a
                         : 0.5 * (x.a * x.h + y.a * y.h) +
                               0.5 * r2 * ((x.g + y.g) - 0.5 * pi);
    return x.sign * y.sign * q;
}

/// The area of the pixel between lines x0 < x1 and y0 < y1 inside the circle.
inline double pixel_overlap(const CircleLine& x0, const CircleLine& x1, const CircleLine& y0,
                            const CircleLine& y1, double r) {
    return (corner_area(x1, y1, r) - corner_area(x0, y1, r)) -
           (corner_area(x1, y0, r) - corner_area(x0, y0, r));
}

/// The area of the rectangle [xmin, xmax] × [ymin, ymax] inside the circle of radius r about
/// the origin (0 for r ≤ 0).
double circle_overlap(double xmin, double ymin, double xmax, double ymax, double r);

/// The run [first, last] of columns in [lo, hi) about `nearest` where `test` holds (first >
/// last: none), for a test that holds on an interval of columns holding `nearest` if on any:
/// from estimates of its ends, moved column by column to where the test changes.
template <class Test>
void run_about(int nearest, int lo, int hi, double first_estimate, double last_estimate,
               Test&& test, int& first, int& last) {
    first = std::clamp(int(std::ceil(first_estimate)), lo, nearest);
    while (first > lo && test(first - 1)) --first;
    while (first <= nearest && !test(first)) ++first;
    last = std::clamp(int(std::floor(last_estimate)), nearest, hi - 1);
    while (last < hi - 1 && test(last + 1)) ++last;
    while (last >= nearest && !test(last)) --last;
}

/// The lines of one circle's box and one row's weights; reused from call to call by each thread.
struct CircleLines {
    std::vector<CircleLine> columns, rows;
    std::vector<double> weights;
};
CircleLines& circle_lines_workspace();

/// Calls row(j, begin, end, weights) for every row j (0-based, in order) of a w × h image that
/// sep_sum_circle(x, y, r) reaches: the pixels it adds there are the columns begin … end − 1,
/// weights[i − begin] the area of pixel i inside the circle. None for a radius that is not
/// positive, or a centre or radius that is not finite.
template <class Row>
void visit_circle_rows(int w, int h, double x, double y, double r, Row&& row) {
    if (!(r > 0.0) || !std::isfinite(r) || !std::isfinite(x) || !std::isfinite(y)) return;
    // sep's box, and its band of pixels within half a diagonal of the edge (r ± 0.7072): those
    // nearer the centre lie inside (weight 1), those beyond it outside. (sep also gives weight 1
    // to a pixel centred on the centre of a circle under 0.7072; here it gets its area.)
    const double r_in = r - 0.7072, r_out = r + 0.7072;
    const double r_in2 = r_in > 0.0 ? r_in * r_in : -1.0, r_out2 = r_out * r_out;
    const int i0 = std::max(int(x - r + 0.5), 0), i1 = std::min(int(x + r + 1.4999999), w);
    const int j0 = std::max(int(y - r + 0.5), 0), j1 = std::min(int(y + r + 1.4999999), h);
    if (i0 >= i1 || j0 >= j1) return;
    CircleLines& lines = circle_lines_workspace();
    lines.columns.resize(std::size_t(i1 - i0 + 1));
    lines.rows.resize(std::size_t(j1 - j0 + 1));
    lines.weights.resize(std::size_t(i1 - i0));
    circle_lines(i0, i1 - i0 + 1, x, r, lines.columns.data());
    circle_lines(j0, j1 - j0 + 1, y, r, lines.rows.data());
    const CircleLine* columns = lines.columns.data() - i0;
    double* weights = lines.weights.data();
    // The box's column nearest the centre: along a row, sep's tests (dx² + dy² against r_out²
    // and r_in²) hold on a run of columns about it, whose ends are found from an estimate.
    const int nearest = std::clamp(int(std::floor(x + 0.5)), i0, i1 - 1);
    for (int j = j0; j < j1; ++j) {
        const double dy = double(j) - y, dy2 = dy * dy;
        const CircleLine &below = lines.rows[std::size_t(j - j0)],
                         &above = lines.rows[std::size_t(j - j0 + 1)];
        auto reached = [&](int i) {
            const double dx = double(i) - x;
            return dx * dx + dy2 < r_out2;
        };
        auto inside = [&](int i) {
            const double dx = double(i) - x;
            return dx * dx + dy2 <= r_in2;
        };
        // The run [first, last] about `nearest` where `test` holds (first > last: none).
        auto run = [&](auto test, double limit2, int& first, int& last) {
            const double half = std::sqrt(std::max(limit2 - dy2, 0.0));
            run_about(nearest, i0, i1, x - half, x + half, test, first, last);
        };
        int first, last;
        run(reached, r_out2, first, last);
        if (first > last) continue;
        const int begin = first, end = last + 1;
        // The band's pixels at either end, weight 1 between them.
        int inner_begin = end, inner_end = end;
        if (r_in2 > 0.0) {
            run(inside, r_in2, first, last);
            if (first <= last) inner_begin = first, inner_end = last + 1;
        }
        // A corner's area is shared by the pixels either side of it.
        auto band = [&](int from, int to) {
            if (from >= to) return;
            double left_above = corner_area(columns[from], above, r),
                   left_below = corner_area(columns[from], below, r);
            for (int i = from; i < to; ++i) {
                const double right_above = corner_area(columns[i + 1], above, r),
                             right_below = corner_area(columns[i + 1], below, r);
                weights[i - begin] = (right_above - left_above) - (right_below - left_below);
                left_above = right_above;
                left_below = right_below;
            }
        };
        band(begin, inner_begin);
        std::fill(weights + (inner_begin - begin), weights + (inner_end - begin), 1.0);
        band(inner_end, end);
        row(j, begin, end, static_cast<const double*>(weights));
    }
}

/// One term of sep's sum: the value as sep reads it (a float) times the pixel's weight.
inline double sep_term(double value, double weight) { return double(float(value)) * weight; }

/// The exact aperture's sum over a row-major w × h image (0 when r is not positive, or a
/// parameter is not finite).
double sum_circle(const double* data, int w, int h, double x, double y, double r);

/// The area of the rectangle [xmin, xmax] × [ymin, ymax] inside the ellipse about the origin
/// of semi-axes a, along the angle θ (radians, counter-clockwise from the x axis), and b.
double ellipse_overlap(double xmin, double ymin, double xmax, double ymax, double a, double b,
                       double theta);

/// The exact elliptical aperture's sum over a row-major w × h image, as sep_sum_ellipse(x, y,
/// a, b, θ, r = 1) with subpix 0 (each value rounded to float, as sep reads it), row by row;
/// 0 when a or b is not positive, or any parameter is not finite.
double sum_ellipse(const double* data, int w, int h, double x, double y, double a, double b,
                   double theta);

}  // namespace shapesim
