// Derivative-free minimisation: Nelder–Mead as scipy.optimize.fmin (non-adaptive: reflection 1,
// expansion 2, contraction ½, shrink ½; outside and inside contraction told apart), over N
// parameters. Morphometry's asymmetry centre (statmorph's choice, so its defaults are scipy's)
// and decompose's elliptical Gaussians use it. Golden-section search in one variable: the β
// searches of decompose (χ²_r) and of the PSF fit (residual sum of squares). Brent's root
// finder: morphometry's Petrosian radius and its light-fraction radii.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <numeric>
#include <utility>

namespace shapesim {

/// How nelder_mead() starts and stops.
struct NelderMeadOptions {
    /// Start simplex: each coordinate moved by `step` when > 0, else (scipy's rule) by 5% of
    /// itself, or 0.00025 when it is 0.
    double step = 0.0;
    double xatol = 1e-6;  ///< stop when every vertex lies within this of the best, per coordinate …
    double fatol = 1e-4;  ///< … and their values within this of the best value
    int max_calls = 400;  ///< or after this many calls of f
    int max_iterations = 400;
};

/// The best vertex found minimising f (std::array<double, N> → double; +∞ marks a forbidden
/// point) from `start`.
template <std::size_t N, class F>
std::array<double, N> nelder_mead(const F& f, const std::array<double, N>& start,
                                  const NelderMeadOptions& options = {}) {
    using V = std::array<double, N>;
    std::array<V, N + 1> v;
    std::array<double, N + 1> fv;
    v[0] = start;
    for (std::size_t k = 0; k < N; ++k) {
        V p = start;
        if (options.step > 0.0) p[k] += options.step;
        else p[k] = p[k] != 0.0 ? 1.05 * p[k] : 0.00025;
        v[k + 1] = p;
    }
    for (std::size_t k = 0; k <= N; ++k) fv[k] = f(v[k]);
    int calls = int(N) + 1, iterations = 1;
    const auto sort = [&] {
        std::array<std::size_t, N + 1> order;
        std::iota(order.begin(), order.end(), std::size_t(0));
        std::stable_sort(order.begin(), order.end(),
                         [&](std::size_t a, std::size_t b) { return fv[a] < fv[b]; });
        std::array<V, N + 1> v2;
        std::array<double, N + 1> f2;
        for (std::size_t k = 0; k <= N; ++k) {
            v2[k] = v[order[k]];
            f2[k] = fv[order[k]];
        }
        v = v2;
        fv = f2;
    };
    sort();
    while (calls < options.max_calls && iterations < options.max_iterations) {
        double size = 0.0, spread = 0.0;
        for (std::size_t k = 1; k <= N; ++k) {
            for (std::size_t d = 0; d < N; ++d) size = std::max(size, std::abs(v[k][d] - v[0][d]));
            spread = std::max(spread, std::abs(fv[0] - fv[k]));
        }
        if (size <= options.xatol && spread <= options.fatol) break;
        V bar{};
        for (std::size_t k = 0; k < N; ++k)
            for (std::size_t d = 0; d < N; ++d) bar[d] += v[k][d];
        for (std::size_t d = 0; d < N; ++d) bar[d] /= double(N);
        const auto point = [&](double t) {
            V p;
            for (std::size_t d = 0; d < N; ++d) p[d] = bar[d] + t * (v[N][d] - bar[d]);
            return p;
        };
        const V xr = point(-1.0);
        const double fr = f(xr);
        ++calls;
        bool shrink = false;
        if (fr < fv[0]) {
            const V xe = point(-2.0);
            const double fe = f(xe);
            ++calls;
            if (fe < fr) v[N] = xe, fv[N] = fe;
            else v[N] = xr, fv[N] = fr;
        } else if (fr < fv[N - 1]) {
            v[N] = xr, fv[N] = fr;
        } else if (fr < fv[N]) {
            const V xc = point(-0.5);
            const double fc = f(xc);
            ++calls;
            if (fc <= fr) v[N] = xc, fv[N] = fc;
            else shrink = true;
        } else {
            const V xcc = point(0.5);
            const double fcc = f(xcc);
            ++calls;
            if (fcc < fv[N]) v[N] = xcc, fv[N] = fcc;
            else shrink = true;
        }
        if (shrink)
            for (std::size_t k = 1; k <= N; ++k) {
                for (std::size_t d = 0; d < N; ++d) v[k][d] = v[0][d] + 0.5 * (v[k][d] - v[0][d]);
                fv[k] = f(v[k]);
                ++calls;
            }
        sort();
        ++iterations;
    }
    return v[0];
}

/// The last bracket of golden_section(): its inner points c < d and their values.
template <class Value>
struct GoldenBracket {
    double c = 0.0, d = 0.0;
    Value fc, fd;
};

/// Golden-section search for a minimum of f (double → Value) on [a, b], until the bracket is
/// no wider than `tolerance`. The inner points are b − g(b − a) and a + g(b − a), g = (√5 − 1)/2;
/// the bracket keeps the side of the point `less` finds lower (the upper one on a tie). f is
/// called once per point, in order; `drop(value)` is given each point's value as the point
/// leaves the bracket (a caller keeping every trial's best). Returns the last inner points.
template <class F, class Less, class Drop>
auto golden_section(const F& f, double a, double b, double tolerance, const Less& less,
                    const Drop& drop) -> GoldenBracket<decltype(f(a))> {
    constexpr double g = 0.6180339887498949;
    double c = b - g * (b - a), d = a + g * (b - a);
    auto fc = f(c);
    auto fd = f(d);
    while (b - a > tolerance) {
        if (less(fc, fd)) {
            drop(fd);
            b = d;
            d = c;
            fd = std::move(fc);
            c = b - g * (b - a);
            fc = f(c);
        } else {
            drop(fc);
            a = c;
            c = d;
            fc = std::move(fd);
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    return {c, d, std::move(fc), std::move(fd)};
}

/// Brent's root finder on a bracket [a, b] with f(a)·f(b) ≤ 0 (fa = f(a) and fb = f(b), known
/// to the caller, whose search found the bracket), absolute tolerance `tol`; at most 200 steps.
template <class F>
double brent_root(const F& f, double a, double b, double fa, double fb, double tol) {
    if (fa == 0.0) return a;
    if (fb == 0.0) return b;
    double c = a, fc = fa, d = b - a, e = d;
    for (int iter = 0; iter < 200; ++iter) {
        if ((fb > 0.0) == (fc > 0.0)) {
            c = a;
            fc = fa;
            d = e = b - a;
        }
        if (std::abs(fc) < std::abs(fb)) {
            a = b;
            b = c;
            c = a;
            fa = fb;
            fb = fc;
            fc = fa;
        }
        const double tol1 = 2.0 * 2.2e-16 * std::abs(b) + 0.5 * tol;
        const double m = 0.5 * (c - b);
        if (std::abs(m) <= tol1 || fb == 0.0) return b;
        if (std::abs(e) >= tol1 && std::abs(fa) > std::abs(fb)) {
            double p, q, r;
            const double s = fb / fa;
            if (a == c) {
                p = 2.0 * m * s;
                q = 1.0 - s;
            } else {
                q = fa / fc;
                r = fb / fc;
                p = s * (2.0 * m * q * (q - r) - (b - a) * (r - 1.0));
                q = (q - 1.0) * (r - 1.0) * (s - 1.0);
            }
            if (p > 0.0) q = -q;
            p = std::abs(p);
            if (2.0 * p < std::min(3.0 * m * q - std::abs(tol1 * q), std::abs(e * q))) {
                e = d;
                d = p / q;
            } else {
                d = m;
                e = d;
            }
        } else {
            d = m;
            e = d;
        }
        a = b;
        fa = fb;
        b += std::abs(d) > tol1 ? d : (m > 0.0 ? tol1 : -tol1);
        fb = f(b);
    }
    return b;
}

}  // namespace shapesim
