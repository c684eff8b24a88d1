// libsep's exact circular aperture (sep_sum_circle with subpix 0, no mask, no noise), redone
// so that one walk over the pixels can weigh several images at once. It must give sep's sums
// bit for bit (the morphology is defined by them), so it repeats sep 1.2's arithmetic in sep's
// order: the box, the band of pixels whose exact overlap is computed (r ± 0.7072), the row-major
// walk, each value rounded to float (sep's PIXTYPE) times its overlap, and the overlap geometry.
// tests/unit/exact_aperture_test.cpp holds it to sep_sum_circle itself.
#pragma once

#include <algorithm>

namespace shapesim {

/// The area of the rectangle [xmin, xmax] × [ymin, ymax] inside the circle of radius r about
/// the origin, computed as sep's circoverlap computes it.
double circle_overlap(double xmin, double ymin, double xmax, double ymax, double r);

/// Calls visit(i, j, weight) on every pixel (column i, row j, 0-based) of a w × h image that
/// sep_sum_circle(x, y, r) adds, in sep's order, with the weight sep gives it. r > 0.
template <class Visit>
void visit_circle(int w, int h, double x, double y, double r, Visit&& visit) {
    const double r_in = r - 0.7072, r_out = r + 0.7072;
    const double r_in2 = r_in > 0.0 ? r_in * r_in : 0.0, r_out2 = r_out * r_out;
    const int i0 = std::max(int(x - r + 0.5), 0), i1 = std::min(int(x + r + 1.4999999), w);
    const int j0 = std::max(int(y - r + 0.5), 0), j1 = std::min(int(y + r + 1.4999999), h);
    for (int j = j0; j < j1; ++j) {
        const double dy = double(j) - y;
        for (int i = i0; i < i1; ++i) {
            const double dx = double(i) - x;
            const double rpix2 = dx * dx + dy * dy;
            if (!(rpix2 < r_out2)) continue;
            // Only the band near the edge needs the exact overlap; sep takes 1 inside it.
            visit(i, j,
                  rpix2 > r_in2 ? circle_overlap(dx - 0.5, dy - 0.5, dx + 0.5, dy + 0.5, r) : 1.0);
        }
    }
}

/// One term of sep's sum: the value as sep reads it (a float) times the pixel's weight.
inline double sep_term(double value, double weight) { return double(float(value)) * weight; }

/// sep_sum_circle's sum over a row-major w × h image (0 when r is not positive).
double sum_circle(const double* data, int w, int h, double x, double y, double r);

}  // namespace shapesim
