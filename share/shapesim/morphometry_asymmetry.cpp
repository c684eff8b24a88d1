// The asymmetry A(c) of measure_morphometry (statmorph's) and its minimum over the centre: a
// hot loop, one walk over the aperture's pixels per centre, in lanes (AVX2) or not, the same bits.
#include "shapesim/morphometry.hpp"

#include "shapesim/exact_aperture.hpp"
#include "shapesim/lane_math.hpp"
#include "shapesim/optimize.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

namespace shapesim {

namespace {

constexpr double nan = std::numeric_limits<double>::quiet_NaN();

using Grid = ImageArray;
using Mask = detail::PixelFlags;
using Centre = std::array<double, 2>;

// std::round (half away from zero), exactly, without the library call: x − trunc(x) is exact.
long round_half_away(double x) {
    const double t = std::trunc(x);
    const double f = x - t;
    return long(t) + (f >= 0.5 ? 1 : (f <= -0.5 ? -1 : 0));
}

// A window of a stamp: columns x0 … x0 + nx − 1, rows y0 … y0 + ny − 1.
struct Window {
    long x0 = 0, y0 = 0, nx = 0, ny = 0;
};

// The pixels a circle of radius r about (x, y) can reach, with 3 pixels to spare, clipped to the
// nx × ny stamp (the whole stamp when r is not a finite positive radius).
Window aperture_box(double x, double y, double r, long nx, long ny) {
    if (!(r > 0.0) || !(r < double(nx + ny))) return {0, 0, nx, ny};
    const long half = long(std::ceil(r)) + 3;
    const long x0 = std::clamp(long(std::floor(x)) - half, 0L, nx),
               x1 = std::clamp(long(std::floor(x)) + half + 1, 0L, nx);
    const long y0 = std::clamp(long(std::floor(y)) - half, 0L, ny),
               y1 = std::clamp(long(std::floor(y)) + half + 1, 0L, ny);
    return {x0, y0, x1 - x0, y1 - y0};
}

// The asymmetry's three sums over a row's run of aperture pixels, in four interleaved partial
// sums each (pixel k of a run into lane k mod 4): lanes of AVX2 and the scalar code add the
// same terms in the same order, so both give the same bits.
struct AsymmetrySums {
    double s_abs[4] = {}, d[4] = {}, area[4] = {};

    // One pixel: value `img`, I₁₈₀ `rot`, aperture weight `weight`, into lane k.
    void add(int k, double img, double rot, double weight) {
        s_abs[k] += sep_term(std::abs(img), weight);
        d[k] += sep_term(std::abs(rot - img), weight);
        area[k] += weight;  // sep_term(1, weight)
    }
    static double total(const double (&lanes)[4]) {
        return (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
    }
};

// A run of aperture pixels whose rotation sources and mirrored mask pixels all lie on the
// stamp: x = 2 x_c − i is then ≥ 0 and exact, so its fraction fx is the run's and ⌊x⌋ falls by
// one per pixel. Rows: `here` (I), `above`/`below` (I₁₈₀'s source rows), `keep_here` and
// `keep_mirror` (all bits set where unmasked); `first_source` = ⌊x⌋ of the run's first pixel,
// `mirror_step` whether x rounds up to the mirrored mask pixel.
struct AsymmetryRun {
    const double *here, *above, *below, *weights;
    const std::uint64_t *keep_here, *keep_mirror;
    long begin, end, first_source;
    int mirror_step;
    double fx, fy;
};

void add_run(const AsymmetryRun& run, AsymmetrySums& sums) {
    for (long i = run.begin; i < run.end; ++i) {
        const long k = i - run.begin, i0 = run.first_source - k;
        if (!(run.keep_here[i] & run.keep_mirror[i0 + run.mirror_step])) continue;
        const double rot =
            (1 - run.fy) * ((1 - run.fx) * run.above[i0] + run.fx * run.above[i0 + 1]) +
            run.fy * ((1 - run.fx) * run.below[i0] + run.fx * run.below[i0 + 1]);
        sums.add(int(k & 3), run.here[i], rot, run.weights[k]);
    }
}

// add_run four pixels at a time; the run's last pixels (under four) one at a time. A masked
// pixel adds +0 to its lane where add_run leaves it out: the same sums (each starts at +0 and
// adds only terms ≥ 0).
__attribute__((target("avx2"))) void add_run_avx2(const AsymmetryRun& run, AsymmetrySums& sums) {
    using lane::Doubles4;
    using lane::Words4;
    using Floats4 = float __attribute__((vector_size(16)));
    // Loads and stores by memcpy, |x| and the masks by vector casts: clang will not pass lanes
    // to a function (a lambda, lane_math's) without the AVX2 target.
    const Words4 magnitude = Words4{} + 0x7fffffffffffffffULL;
    Doubles4 s_abs, d, area;
    std::memcpy(&s_abs, sums.s_abs, sizeof s_abs);
    std::memcpy(&d, sums.d, sizeof d);
    std::memcpy(&area, sums.area, sizeof area);
    const Doubles4 fx = Doubles4{} + run.fx, gx = Doubles4{} + (1 - run.fx),
                   fy = Doubles4{} + run.fy, gy = Doubles4{} + (1 - run.fy);
    long i = run.begin;
    for (; i + 4 <= run.end; i += 4) {
        const long k = i - run.begin, i0 = run.first_source - k;  // lanes' sources i0 … i0 − 3
        Doubles4 a0, a1, b0, b1, img, weight;
        Words4 mirror, keep;
        std::memcpy(&a0, run.above + i0 - 3, sizeof a0);
        std::memcpy(&a1, run.above + i0 - 2, sizeof a1);
        std::memcpy(&b0, run.below + i0 - 3, sizeof b0);
        std::memcpy(&b1, run.below + i0 - 2, sizeof b1);
        std::memcpy(&mirror, run.keep_mirror + i0 + run.mirror_step - 3, sizeof mirror);
        std::memcpy(&keep, run.keep_here + i, sizeof keep);
        std::memcpy(&img, run.here + i, sizeof img);
        std::memcpy(&weight, run.weights + k, sizeof weight);
        a0 = __builtin_shufflevector(a0, a0, 3, 2, 1, 0);
        a1 = __builtin_shufflevector(a1, a1, 3, 2, 1, 0);
        b0 = __builtin_shufflevector(b0, b0, 3, 2, 1, 0);
        b1 = __builtin_shufflevector(b1, b1, 3, 2, 1, 0);
        keep &= __builtin_shufflevector(mirror, mirror, 3, 2, 1, 0);
        const Doubles4 rot = gy * (gx * a0 + fx * a1) + fy * (gx * b0 + fx * b1);
        const Doubles4 abs_img = __builtin_convertvector(
                           __builtin_convertvector((Doubles4)((Words4)img & magnitude), Floats4),
                           Doubles4),
                       abs_diff = __builtin_convertvector(
                           __builtin_convertvector((Doubles4)((Words4)(rot - img) & magnitude),
                                                   Floats4),
                           Doubles4);
        s_abs += (Doubles4)((Words4)(abs_img * weight) & keep);
        d += (Doubles4)((Words4)(abs_diff * weight) & keep);
        area += (Doubles4)((Words4)weight & keep);
    }
    std::memcpy(sums.s_abs, &s_abs, sizeof s_abs);
    std::memcpy(sums.d, &d, sizeof d);
    std::memcpy(sums.area, &area, sizeof area);
    // GCC leaves the upper halves dirty here, and SSE code after it (the call below, and the
    // caller) then runs several times slower on this machine's CPU.
    _mm256_zeroupper();
    AsymmetryRun rest = run;
    rest.begin = i;
    rest.first_source = run.first_source - (i - run.begin);
    rest.weights = run.weights + (i - run.begin);
    // add_run numbers lanes from its own first pixel, which is a multiple of 4 from the run's.
    add_run(rest, sums);
}

// The asymmetry about a centre, in a circle of radius r (statmorph): Σ|I − I₁₈₀| less the sky's
// share, over Σ|I|, with the mask made symmetric. Minimised over the centre (Nelder–Mead), so
// it is a hot loop: one walk over the aperture's pixels, no images built.
class Asymmetry {
public:
    Asymmetry(const Grid& z, const Mask& masked, double r, double sky_asymmetry)
        : z_(z), keep_(masked.rows(), masked.cols()), r_(r),
          sky_asymmetry_(sky_asymmetry), lanes_(lane::have_avx2()) {
        for (long j = 0; j < masked.rows(); ++j)
            for (long i = 0; i < masked.cols(); ++i) keep_(j, i) = masked(j, i) ? 0 : ~0ULL;
    }

    double operator()(const Centre& c) const {
        const long ny = z_.rows(), nx = z_.cols();
        const double xc = c[0], yc = c[1];
        if (xc < 0.0 || xc >= double(nx) || yc < 0.0 || yc >= double(ny)) {
            left_stamp_ = true;
            return 100.0;
        }
        // The box of pixels the aperture can touch (its radius and 3 pixels, clipped to the
        // stamp, as sep clips the circle's own box), with the aperture's centre in it: the sums
        // over |I|, |I₁₈₀ − I| and the unmasked indicator are those over the whole stamp. One
        // walk gives all three (exact_aperture.hpp), computing each pixel's overlap once and
        // rotating only the pixels the circle reaches.
        const Window box = aperture_box(xc, yc, r_, nx, ny);
        const double bx = xc - double(box.x0), by = yc - double(box.y0);  // exact
        // Row by row, the aperture's run of pixels and their weights, then the sums over it:
        // what depends on the row only (I₁₈₀'s two source rows, the mirrored mask's row) is
        // found once per row.
        AsymmetrySums sums;
        if (r_ > 0.0)
            visit_circle_rows(int(box.nx), int(box.ny), bx, by, r_,
                              [&](int b, int begin, int end, const double* weights) {
                                  add_row(xc, yc, box.y0 + b, box.x0 + begin, box.x0 + end,
                                          weights, sums);
                              });
        const double s_abs = AsymmetrySums::total(sums.s_abs);
        if (!(s_abs > 0.0)) return nan;
        return (AsymmetrySums::total(sums.d) - AsymmetrySums::total(sums.area) * sky_asymmetry_) /
               s_abs;
    }
    // Whether the search tried a centre off the stamp.
    bool left_stamp() const { return left_stamp_; }

private:
    // The sums over row j's aperture pixels begin … end − 1 (stamp columns), of weights
    // `weights`, for the centre (xc, yc).
    void add_row(double xc, double yc, long j, long begin, long end, const double* weights,
                 AsymmetrySums& sums) const {
        const long ny = z_.rows(), nx = z_.cols();
        // I₁₈₀(j, i) = I(2 yc − j, 2 xc − i), bilinear, zero outside the stamp.
        const double y = 2.0 * yc - double(j);
        const double y0 = std::floor(y), fy = y - y0;
        const long j0 = long(y0), rj = round_half_away(y);
        const double* above = j0 >= 0 && j0 < ny ? &z_(j0, 0) : nullptr;
        const double* below = j0 + 1 >= 0 && j0 + 1 < ny ? &z_(j0 + 1, 0) : nullptr;
        const std::uint64_t* mirror_row = rj >= 0 && rj < ny ? &keep_(rj, 0) : nullptr;
        // x = 2 xc − i falls with i, and so do ⌊x⌋ and x rounded: the run's ends bound them.
        const double x_first = 2.0 * xc - double(begin), x_last = 2.0 * xc - double(end - 1);
        const bool inside = above != nullptr && below != nullptr && mirror_row != nullptr &&
                            long(std::floor(x_last)) >= 0 && long(std::floor(x_first)) + 1 < nx &&
                            round_half_away(x_last) >= 0 && round_half_away(x_first) < nx;
        if (inside) {
            const double x0 = std::floor(x_first), fx = x_first - x0;
            const AsymmetryRun on_stamp{&z_(j, 0), above,    below, weights,  &keep_(j, 0),
                                        mirror_row, begin, end, long(x0), fx >= 0.5 ? 1 : 0,
                                        fx,         fy};
            if (lanes_)
                add_run_avx2(on_stamp, sums);
            else
                add_run(on_stamp, sums);
            return;
        }
        // Some source or mirrored mask pixel may lie off the stamp: then 0, unmasked.
        auto at = [&](const double* row, long a) {
            return (row == nullptr || a < 0 || a >= nx) ? 0.0 : row[a];
        };
        const std::uint64_t* keep_here = &keep_(j, 0);
        for (long i = begin; i < end; ++i) {
            const double x = 2.0 * xc - double(i);
            const double x0 = std::floor(x), fx = x - x0;
            const long i0 = long(x0);
            // The mask rotated by nearest neighbour (half away from zero), then OR. A masked
            // pixel (I and I₁₈₀ set to 0) is left out of the sums.
            const long ri = round_half_away(x);
            const bool mirror_masked =
                mirror_row != nullptr && ri >= 0 && ri < nx && !mirror_row[ri];
            if (!keep_here[i] || mirror_masked) continue;
            const double rot = (1 - fy) * ((1 - fx) * at(above, i0) + fx * at(above, i0 + 1)) +
                               fy * ((1 - fx) * at(below, i0) + fx * at(below, i0 + 1));
            sums.add(int((i - begin) & 3), z_(j, i), rot, weights[i - begin]);
        }
    }

    const Grid& z_;
    // All bits set where the pixel is unmasked, none where it is masked.
    Eigen::Array<std::uint64_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> keep_;
    double r_, sky_asymmetry_;
    bool lanes_;
    mutable bool left_stamp_ = false;
};

}  // namespace

detail::AsymmetryCentre detail::minimise_asymmetry(const ImageArray& z, const PixelFlags& masked,
                                                   double r, double sky_asymmetry,
                                                   const std::array<double, 2>& start) {
    const Asymmetry asymmetry(z, masked, r, sky_asymmetry);
    Centre centre = nelder_mead<2>(asymmetry, start);
    const bool left_stamp = asymmetry.left_stamp();
    if (left_stamp) centre = start;
    return {centre, asymmetry(centre), left_stamp};
}

}  // namespace shapesim
