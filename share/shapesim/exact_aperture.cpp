#include "shapesim/exact_aperture.hpp"

#include "shapesim/constants.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace shapesim {

double circle_overlap(double xmin, double ymin, double xmax, double ymax, double r) {
    if (!(r > 0.0)) return 0.0;
    return pixel_overlap(circle_line(xmin, r), circle_line(xmax, r), circle_line(ymin, r),
                         circle_line(ymax, r), r);
}

namespace {

// Four lines a lane group: the asin, square root and division of each (the corner areas' only
// costly steps) share their instructions. Compiled for AVX2 and for the baseline, chosen by
// lane::have_avx2 (clang will not pass lanes to lane_math's helpers from a target_clones
// function's baseline copy).
__attribute__((always_inline)) inline void circle_lines_lanes(int first, int count, double x,
                                                             double r, CircleLine* out) {
    using lane::Doubles4;
    const Doubles4 radius = Doubles4{} + r;
    int n = 0;
    for (; n + 4 <= count; n += 4) {
        const double i = double(first + n);
        const Doubles4 t = (Doubles4{i, i + 1.0, i + 2.0, i + 3.0} - 0.5) - x;
        const Doubles4 at = lane::abs(t);
        const Doubles4 a = lane::select(radius < at, radius, at);  // std::min(|t|, r)
        const Doubles4 h = lane::sqrt((radius - a) * (radius + a));
        const Doubles4 g = lane::asin(a / radius);
        for (int j = 0; j < 4; ++j) out[n + j] = {t[j] < 0.0 ? -1.0 : 1.0, a[j], h[j], g[j]};
    }
    for (; n < count; ++n) out[n] = circle_line((double(first + n) - 0.5) - x, r);
}

__attribute__((target("avx2"))) void circle_lines_avx2(int first, int count, double x, double r,
                                                       CircleLine* out) {
    circle_lines_lanes(first, count, x, r, out);
}

}  // namespace

void circle_lines(int first, int count, double x, double r, CircleLine* out) {
    if (lane::have_avx2())
        circle_lines_avx2(first, count, x, r, out);
    else
        circle_lines_lanes(first, count, x, r, out);
}

CircleLines& circle_lines_workspace() {
    thread_local CircleLines lines;
    return lines;
}

double sum_circle(const double* data, int w, int h, double x, double y, double r) {
    double sum = 0.0;
    visit_circle_rows(w, h, x, y, r, [&](int j, int begin, int end, const double* weights) {
        const double* row = data + long(j) * w;
        for (int i = begin; i < end; ++i) sum += sep_term(row[i], weights[i - begin]);
    });
    return sum;
}

// --- the ellipse -------------------------------------------------------------------------
//
// Scaled along its minor axis by k = a/b, the ellipse is the circle of radius a, a pixel a
// parallelogram (area k) and the overlap 1/k of the area of the circle inside it. That area is,
// by Green's theorem, half the sum of P × Q over the parts PQ of the pixel's edges inside the
// circle, plus a²/2 times the angles of the arcs of the circle inside the pixel that join them.
// The edges lie on two families of parallel lines (the images of the pixel columns' and rows'
// edges); a line at signed distance σ from the centre, along unit direction d with normal
// m = (d_y, −d_x), meets the circle at ±h = ±√(a² − σ²) along d, at the angles ψ ∓ α where
// ψ = atan2(m) is the family's and α = acos(σ/a) the line's: one transcendental per line, and
// the arcs are differences of them.
namespace {

constexpr double two_pi = 2.0 * pi;

struct Family {
    double dx, dy;  // unit direction in the scaled frame
    double mx, my;  // its normal, (d_y, −d_x)
    double psi;     // atan2(m_y, m_x)
};

struct Line {
    double sigma, h, alpha;  // distance along m, half-chord, acos(σ/a)
};

class ScaledEllipse {
public:
    ScaledEllipse(double a, double b, double theta)
        : c_(std::cos(theta)), s_(std::sin(theta)), k_(a / b), r_(a),
          column_(family(s_, k_ * c_)), row_(family(c_, -k_ * s_)) {}

    double k() const { return k_; }
    // Half the width and height of the ellipse's bounding box.
    double half_width() const { return std::hypot(r_ * c_, (r_ / k_) * s_); }
    double half_height() const { return std::hypot(r_ * s_, (r_ / k_) * c_); }
    // The scaled frame's coordinates of the offset (px, py) from the centre.
    double u(double px, double py) const { return px * c_ + py * s_; }
    double v(double px, double py) const { return k_ * (py * c_ - px * s_); }
    // The squared distance of (px, py) from the centre in the scaled frame.
    double rho2(double px, double py) const {
        const double U = u(px, py), V = v(px, py);
        return U * U + V * V;
    }
    // Along the row py, ρ² = A (px − p*)² + k² py²/A with A = c² + k² s² and
    // p* = −py c s (1 − k²)/A: the offset p* nearest the centre, and the half-width of the
    // part of the row where ρ² ≤ limit2.
    double row_middle(double py) const { return py * middle_slope_; }
    double row_half_width(double py, double limit2) const {
        return std::sqrt(std::max(limit2 - k2_over_a_ * py * py, 0.0) * inverse_a_);
    }
    // How far a pixel's corners lie from its centre in the scaled frame: half the longer
    // diagonal of the parallelogram whose sides are the images (c, −k s) and (s, k c) of the
    // pixel's, |s₁ ± s₂|² = 1 + k² ± 2 c s (1 − k²).
    double half_diagonal() const {
        return 0.5 * std::sqrt(1.0 + k_ * k_ + 2.0 * std::abs(c_ * s_ * (1.0 - k_ * k_)));
    }
    Line column_line(double px) const { return line(column_, u(px, 0.0), v(px, 0.0)); }
    Line row_line(double py) const { return line(row_, u(0.0, py), v(0.0, py)); }

    // The area (unscaled) of the pixel [xl, xr] × [yb, yt] inside the ellipse, its edges on
    // the lines left, right, bottom and top.
    double pixel_area(double xl, double xr, double yb, double yt, const Line& left,
                      const Line& right, const Line& bottom, const Line& top) const {
        // Corners counter-clockwise (the scaling keeps the orientation), each found inside or
        // outside once, for both edges that share it.
        const double px[4] = {xl, xr, xr, xl}, py[4] = {yb, yb, yt, yt};
        double U[4], V[4];
        bool inside[4];
        for (int n = 0; n < 4; ++n) {
            U[n] = u(px[n], py[n]);
            V[n] = v(px[n], py[n]);
            inside[n] = U[n] * U[n] + V[n] * V[n] <= r_ * r_;
        }
        // A convex pixel with its corners inside the ellipse lies inside it.
        if (inside[0] && inside[1] && inside[2] && inside[3]) return (xr - xl) * (yt - yb);
        struct Edge {
            const Family* family;
            const Line* line;
            bool forward;  // along +d
        };
        const Edge edges[4] = {{&row_, &bottom, true},
                               {&column_, &right, true},
                               {&row_, &top, false},
                               {&column_, &left, false}};
        // The parts inside: entry and exit points, and where on the circle (angles) if there.
        struct Part {
            double x0, y0, x1, y1;
            bool entry_on_circle, exit_on_circle;
            double entry_angle, exit_angle;
            int edge;
        };
        Part parts[4];
        int count = 0;
        for (int n = 0; n < 4; ++n) {
            const int e = (n + 1) % 4;
            const Edge& edge = edges[n];
            const Family& f = *edge.family;
            const Line& l = *edge.line;
            const bool crosses = std::abs(l.sigma) < r_;
            if (!inside[n] && !inside[e]) {
                // Both ends outside: the edge holds the whole chord or none of it.
                if (!crosses) continue;
                const double ts = U[n] * f.dx + V[n] * f.dy, te = U[e] * f.dx + V[e] * f.dy;
                if ((ts < 0.0) == (te < 0.0)) continue;
            }
            const double sign = edge.forward ? 1.0 : -1.0;
            Part p{};
            p.edge = n;
            if (inside[n]) {
                p.x0 = U[n];
                p.y0 = V[n];
            } else {  // enters at τ = ∓h
                const double t = -sign * l.h;
                p.x0 = l.sigma * f.mx + t * f.dx;
                p.y0 = l.sigma * f.my + t * f.dy;
                p.entry_on_circle = true;
                p.entry_angle = f.psi - sign * l.alpha;
            }
            if (inside[e]) {
                p.x1 = U[e];
                p.y1 = V[e];
            } else {  // leaves at τ = ±h
                const double t = sign * l.h;
                p.x1 = l.sigma * f.mx + t * f.dx;
                p.y1 = l.sigma * f.my + t * f.dy;
                p.exit_on_circle = true;
                p.exit_angle = f.psi + sign * l.alpha;
            }
            parts[count++] = p;
        }
        if (count == 0) {
            // No edge reaches the circle: it lies inside the pixel, or outside it.
            return xl <= 0.0 && 0.0 <= xr && yb <= 0.0 && 0.0 <= yt ? pi * r_ * r_ / k_ : 0.0;
        }
        double twice_area = 0.0, arcs = 0.0;
        for (int n = 0; n < count; ++n) {
            const Part& p = parts[n];
            twice_area += p.x0 * p.y1 - p.y0 * p.x1;
            if (!p.exit_on_circle) continue;
            const Part& next = parts[(n + 1) % count];
            double arc;
            if (count == 1) {
                // From the line's own exit round to its entry: 2π − 2α forward, 2α backward
                // (exact at tangency, where the difference of the angles is 0 or 2π).
                const Line& l = *edges[p.edge].line;
                arc = edges[p.edge].forward ? two_pi - 2.0 * l.alpha : 2.0 * l.alpha;
            } else {
                arc = std::fmod(next.entry_angle - p.exit_angle, two_pi);
                if (arc < 0.0) arc += two_pi;
                // Exit and entry on two lines coincide only where a corner lies on the circle;
                // there the arc is empty (a convex pixel cannot hold all of the circle but a
                // sliver beyond a corner).
                if (arc > two_pi - 1e-9) arc = 0.0;
            }
            arcs += arc;
        }
        return 0.5 * (twice_area + r_ * r_ * arcs) / k_;
    }

private:
    static Family family(double dx, double dy) {
        const double n = std::hypot(dx, dy);
        Family f{dx / n, dy / n, dy / n, -dx / n, 0.0};
        f.psi = std::atan2(f.my, f.mx);
        return f;
    }
    // The line of family f through the point (U, V) of the scaled frame.
    Line line(const Family& f, double U, double V) const {
        const double sigma = U * f.mx + V * f.my;
        const double t = std::min(std::abs(sigma), r_);
        return {sigma, std::sqrt((r_ - t) * (r_ + t)),
                std::acos(std::clamp(sigma / r_, -1.0, 1.0))};
    }

    double c_, s_, k_, r_;
    Family column_, row_;
    // The rows' parabolas (row_middle): 1/A, −c s (1 − k²)/A and k²/A.
    double inverse_a_ = 1.0 / (c_ * c_ + k_ * k_ * s_ * s_);
    double middle_slope_ = -c_ * s_ * (1.0 - k_ * k_) * inverse_a_;
    double k2_over_a_ = k_ * k_ * inverse_a_;
};

}  // namespace

double ellipse_overlap(double xmin, double ymin, double xmax, double ymax, double a, double b,
                       double theta) {
    if (!(a > 0.0 && b > 0.0) || !std::isfinite(a) || !std::isfinite(b)) return 0.0;
    const ScaledEllipse e(a, b, theta);
    return e.pixel_area(xmin, xmax, ymin, ymax, e.column_line(xmin), e.column_line(xmax),
                        e.row_line(ymin), e.row_line(ymax));
}

double sum_ellipse(const double* data, int w, int h, double x, double y, double a, double b,
                   double theta) {
    if (!(a > 0.0 && b > 0.0) || w <= 0 || h <= 0) return 0.0;
    for (double p : {x, y, a, b, theta})
        if (!std::isfinite(p)) return 0.0;
    const ScaledEllipse e(a, b, theta);
    // The ellipse's bounding box, a pixel wider each way, on the image.
    const double ex = e.half_width(), ey = e.half_height();
    const int i0 = std::max(int(std::floor(x - ex - 1.0)), 0),
              i1 = std::min(int(std::ceil(x + ex + 1.0)) + 1, w);
    const int j0 = std::max(int(std::floor(y - ey - 1.0)), 0),
              j1 = std::min(int(std::ceil(y + ey + 1.0)) + 1, h);
    if (i0 >= i1 || j0 >= j1) return 0.0;
    // The band of pixels whose centres lie within a half-diagonal of the edge (in the scaled
    // frame) gets the exact area; those nearer the centre lie inside, those beyond outside.
    const double reach = e.half_diagonal() * 1.0000001;  // a margin for its rounding
    const double r_in = a - reach, r_out = a + reach;
    const double r_in2 = r_in > 0.0 ? r_in * r_in : -1.0, r_out2 = r_out * r_out;
    // The grid's lines (offsets from the centre, and as the scaled frame sees them), reused
    // from call to call by each thread.
    thread_local std::vector<double> column_at, row_at;
    thread_local std::vector<Line> columns, rows;
    column_at.resize(std::size_t(i1 - i0 + 1));
    columns.resize(column_at.size());
    row_at.resize(std::size_t(j1 - j0 + 1));
    rows.resize(row_at.size());
    for (int i = i0; i <= i1; ++i) {
        const std::size_t n = std::size_t(i - i0);
        column_at[n] = (double(i) - 0.5) - x;
        columns[n] = e.column_line(column_at[n]);
    }
    for (int j = j0; j <= j1; ++j) {
        const std::size_t n = std::size_t(j - j0);
        row_at[n] = (double(j) - 0.5) - y;
        rows[n] = e.row_line(row_at[n]);
    }
    double sum = 0.0;
    for (int j = j0; j < j1; ++j) {
        const std::size_t b = std::size_t(j - j0);
        const double dy = double(j) - y;
        const double* row = data + long(j) * w;
        // Along the row the pixels within r_out, and within them those within r_in, are runs
        // about the column nearest the middle of the ellipse's chord (ρ² is a parabola in i).
        const double middle = x + e.row_middle(dy);
        const int nearest = std::clamp(int(std::floor(middle + 0.5)), i0, i1 - 1);
        auto reached = [&](int i) { return e.rho2(double(i) - x, dy) < r_out2; };
        auto inside = [&](int i) { return e.rho2(double(i) - x, dy) <= r_in2; };
        int first, last;
        const double out_half = e.row_half_width(dy, r_out2);
        run_about(nearest, i0, i1, middle - out_half, middle + out_half, reached, first, last);
        if (first > last) continue;
        const int begin = first, end = last + 1;
        int inner_begin = end, inner_end = end;
        if (r_in2 > 0.0) {
            const double in_half = e.row_half_width(dy, r_in2);
            run_about(nearest, i0, i1, middle - in_half, middle + in_half, inside, first, last);
            if (first <= last) inner_begin = first, inner_end = last + 1;
        }
        auto band = [&](int from, int to) {
            for (int i = from; i < to; ++i) {
                const std::size_t l = std::size_t(i - i0);
                sum += sep_term(row[i], e.pixel_area(column_at[l], column_at[l + 1], row_at[b],
                                                     row_at[b + 1], columns[l], columns[l + 1],
                                                     rows[b], rows[b + 1]));
            }
        };
        band(begin, inner_begin);
        for (int i = inner_begin; i < inner_end; ++i) sum += sep_term(row[i], 1.0);
        band(inner_end, end);
    }
    return sum;
}

}  // namespace shapesim
