#include "shapesim/exact_aperture.hpp"

namespace shapesim {

double circle_overlap(double xmin, double ymin, double xmax, double ymax, double r) {
    if (!(r > 0.0)) return 0.0;
    return pixel_overlap(circle_line(xmin, r), circle_line(xmax, r), circle_line(ymin, r),
                         circle_line(ymax, r), r);
}

CircleLines& circle_lines_workspace() {
    thread_local CircleLines lines;
    return lines;
}

double sum_circle(const double* data, int w, int h, double x, double y, double r) {
    if (!(r > 0.0)) return 0.0;
    double sum = 0.0;
    visit_circle_rows(w, h, x, y, r, [&](int j, int begin, int end, const double* weights) {
        const double* row = data + long(j) * w;
        for (int i = begin; i < end; ++i) sum += sep_term(row[i], weights[i - begin]);
    });
    return sum;
}

}  // namespace shapesim
