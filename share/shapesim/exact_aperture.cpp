#include "shapesim/exact_aperture.hpp"

#include <cmath>

namespace shapesim {

namespace {

// Every expression below keeps sep's operand order: a reordered sum is a different double.

// The circular segment cut off by the chord (x1, y1)–(x2, y2) of a circle of radius r.
double segment_area(double x1, double y1, double x2, double y2, double r) {
    const double chord = std::sqrt((x2 - x1) * (x2 - x1) + (y2 - y1) * (y2 - y1));
    const double theta = 2. * std::asin(0.5 * chord / r);
    return 0.5 * r * r * (theta - std::sin(theta));
}

double triangle_area(double x1, double y1, double x2, double y2, double x3, double y3) {
    return 0.5 * std::fabs(x1 * (y2 - y3) + x2 * (y3 - y1) + x3 * (y1 - y2));
}

// The overlap of a rectangle in the first quadrant (0 ≤ x0 ≤ x1, 0 ≤ y0 ≤ y1) with the circle:
// by which of its corners lie inside.
double quadrant_overlap(double x0, double y0, double x1, double y1, double r) {
    const double x02 = x0 * x0, y02 = y0 * y0, r2 = r * r;
    if (x02 + y02 > r2) return 0.;
    const double x12 = x1 * x1, y12 = y1 * y1;
    if (x12 + y12 < r2) return (x1 - x0) * (y1 - y0);
    const bool lower_right = x12 + y02 < r2, upper_left = x02 + y12 < r2;
    if (lower_right && upper_left) {
        const double ax = std::sqrt(r2 - y12), by = std::sqrt(r2 - x12);
        return (x1 - x0) * (y1 - y0) - triangle_area(ax, y1, x1, by, x1, y1) +
               segment_area(ax, y1, x1, by, r);
    }
    if (lower_right) {
        const double ay = std::sqrt(r2 - x02), by = std::sqrt(r2 - x12);
        return segment_area(x0, ay, x1, by, r) + triangle_area(x0, ay, x0, y0, x1, y0) +
               triangle_area(x0, ay, x1, y0, x1, by);
    }
    if (upper_left) {
        const double ax = std::sqrt(r2 - y02), bx = std::sqrt(r2 - y12);
        return segment_area(ax, y0, bx, y1, r) + triangle_area(ax, y0, x0, y0, x0, y1) +
               triangle_area(ax, y0, x0, y1, bx, y1);
    }
    const double ax = std::sqrt(r2 - y02), by = std::sqrt(r2 - x02);
    return segment_area(ax, y0, x0, by, r) + triangle_area(ax, y0, x0, by, x0, y0);
}

}  // namespace

double circle_overlap(double xmin, double ymin, double xmax, double ymax, double r) {
    if (r <= 0.) return 0.;
    // Rectangles within one quadrant are mirrored into the first; the others are cut at the
    // axes (in sep's order of the pieces).
    const bool right = 0. <= xmin, left = 0. >= xmax, above = 0. <= ymin, below = 0. >= ymax;
    if (right || left) {
        if (above) return right ? quadrant_overlap(xmin, ymin, xmax, ymax, r)
                                : quadrant_overlap(-xmax, ymin, -xmin, ymax, r);
        if (below) return right ? quadrant_overlap(-ymax, xmin, -ymin, xmax, r)
                                : quadrant_overlap(-xmax, -ymax, -xmin, -ymin, r);
        return circle_overlap(xmin, ymin, xmax, 0., r) + circle_overlap(xmin, 0., xmax, ymax, r);
    }
    if (above || below)
        return circle_overlap(xmin, ymin, 0., ymax, r) + circle_overlap(0., ymin, xmax, ymax, r);
    return circle_overlap(xmin, ymin, 0., 0., r) + circle_overlap(0., ymin, xmax, 0., r) +
           circle_overlap(xmin, 0., 0., ymax, r) + circle_overlap(0., 0., xmax, ymax, r);
}

double sum_circle(const double* data, int w, int h, double x, double y, double r) {
    if (!(r > 0.0)) return 0.0;
    double sum = 0.0;
    visit_circle(w, h, x, y, r, [&](int i, int j, double weight) {
        sum += sep_term(data[long(j) * w + i], weight);
    });
    return sum;
}

}  // namespace shapesim
