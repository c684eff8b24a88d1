// Correlated noise (pixel_noise.hpp): white noise through a kernel, summed directly over its
// taps in single precision, as many pixels at a time as the lanes hold.
#include "shapesim/pixel_noise.hpp"

#include "shapesim/error.hpp"
#include "shapesim/lane_math.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

namespace shapesim {

namespace {

using lane::have_avx512;

using Floats8 = float __attribute__((vector_size(32)));

struct TapRows {
    const float* const* a;  ///< per tap, the row holding w(p + d) for pixel 0
    const float* const* b;  ///< per paired tap, w(p − d); null for single taps
    const float* weight;
    std::size_t count;
};

// out[i] = Σ_t weight_t (a_t[i] + b_t[i]) (or weight_t a_t[i]), taps in order, for pixels
// from `i` on, four lane groups of V at a time (`i` is left at the first pixel of an unfinished
// four, for sum_taps_one and sum_taps_tail). Four independent sums keep the adder busy (one sum's
// taps wait on each other), and each pixel is still its own sum in tap order, the same bits in any
// width.
template <class V>
__attribute__((always_inline)) inline void sum_taps_lanes(const TapRows& taps, long nx, float* out,
                                                          long& i) {
    constexpr long w = long(sizeof(V) / sizeof(float));
    auto load = [](const float* from) {
        V v;
        std::memcpy(&v, from, sizeof v);
        return v;
    };
    for (; i + 4 * w <= nx; i += 4 * w) {
        V acc0 = {}, acc1 = {}, acc2 = {}, acc3 = {};
        for (std::size_t t = 0; t < taps.count; ++t) {
            const float weight = taps.weight[t];
            const float* a = taps.a[t] + i;
            if (taps.b[t]) {
                const float* b = taps.b[t] + i;
                acc0 = acc0 + weight * (load(a) + load(b));
                acc1 = acc1 + weight * (load(a + w) + load(b + w));
                acc2 = acc2 + weight * (load(a + 2 * w) + load(b + 2 * w));
                acc3 = acc3 + weight * (load(a + 3 * w) + load(b + 3 * w));
            } else {
                acc0 = acc0 + weight * load(a);
                acc1 = acc1 + weight * load(a + w);
                acc2 = acc2 + weight * load(a + 2 * w);
                acc3 = acc3 + weight * load(a + 3 * w);
            }
        }
        std::memcpy(out + i, &acc0, sizeof acc0);
        std::memcpy(out + i + w, &acc1, sizeof acc1);
        std::memcpy(out + i + 2 * w, &acc2, sizeof acc2);
        std::memcpy(out + i + 3 * w, &acc3, sizeof acc3);
    }
}

// The same sums one lane group at a time.
template <class V>
__attribute__((always_inline)) inline void sum_taps_one(const TapRows& taps, long nx, float* out,
                                                        long& i) {
    constexpr long w = long(sizeof(V) / sizeof(float));
    for (; i + w <= nx; i += w) {
        V acc = {};
        for (std::size_t t = 0; t < taps.count; ++t) {
            V v;
            std::memcpy(&v, taps.a[t] + i, sizeof v);
            if (taps.b[t]) {
                V u;
                std::memcpy(&u, taps.b[t] + i, sizeof u);
                v = v + u;
            }
            acc = acc + taps.weight[t] * v;
        }
        std::memcpy(out + i, &acc, sizeof acc);
    }
}

// The pixels from i on one at a time, by the same sums.
void sum_taps_tail(const TapRows& taps, long nx, float* out, long i) {
    for (; i < nx; ++i) {
        float acc = 0.0f;
        for (std::size_t t = 0; t < taps.count; ++t) {
            float v = taps.a[t][i];
            if (taps.b[t]) v = v + taps.b[t][i];
            acc = acc + taps.weight[t] * v;
        }
        out[i] = acc;
    }
}

__attribute__((target_clones("avx2", "default"))) void sum_taps(const TapRows& taps, long nx,
                                                               float* out) {
    long i = 0;
    if (taps.count >= 16) sum_taps_lanes<Floats8>(taps, nx, out, i);  // see sum_taps_avx512
    sum_taps_one<Floats8>(taps, nx, out, i);
    sum_taps_tail(taps, nx, out, i);
}

#ifdef SHAPESIM_LANES_X86
// Sixteen pixels a lane group (the HDF's measured kernel has ~145 taps).
__attribute__((target("avx512f"))) void sum_taps_avx512(const TapRows& taps, long nx, float* out) {
    using Floats16 = float __attribute__((vector_size(64)));
    long i = 0;
    // Four sums at once pay where the taps are many (the measured kernel: 0.42 -> 0.39 s of
    // noise on the HDF scene); with drizzle's five, one at a time is faster (4.3 against 6.2
    // ns/pixel on BM_Noise/1). The same bits either way.
    if (taps.count >= 16) sum_taps_lanes<Floats16>(taps, nx, out, i);
    sum_taps_one<Floats16>(taps, nx, out, i);
    sum_taps_one<Floats8>(taps, nx, out, i);
    sum_taps_tail(taps, nx, out, i);
}
#endif

}  // namespace

CorrelatedNoise::CorrelatedNoise(const NoiseKernel& kernel, std::uint64_t seed, long first, long nx)
    : white_(seed), radius_(kernel.radius), first_(first), nx_(nx) {
    require(nx >= 0, "correlated noise: negative width");
    const int K = radius_, width = 2 * K + 1;
    const std::vector<double> k = kernel.dense();
    auto at = [&](int dx, int dy) { return k[std::size_t((dy + K) * width + dx + K)]; };
    double peak = 0.0;
    for (const double v : k) peak = std::max(peak, std::abs(v));
    // Taps over the half plane (dy > 0, or dy = 0 and dx ≥ 0); k(d) and k(−d) share one
    // multiply when they agree to single precision (they are equal up to the SVD's rounding).
    for (int dy = 0; dy <= K; ++dy)
        for (int dx = dy == 0 ? 0 : -K; dx <= K; ++dx) {
            const double here = at(dx, dy), there = at(-dx, -dy);
            if (dx == 0 && dy == 0) {
                if (here != 0.0) taps_.push_back({float(here), 0, 0, false});
            } else if (std::abs(here - there) <= 1e-7 * peak) {
                if (here != 0.0 || there != 0.0)
                    taps_.push_back({float(0.5 * (here + there)), dx, dy, true});
            } else {
                if (here != 0.0) taps_.push_back({float(here), dx, dy, false});
                if (there != 0.0) taps_.push_back({float(there), -dx, -dy, false});
            }
        }
    ring_.assign(std::size_t(width) * std::size_t(nx + 2 * K), 0.0f);
    a_.resize(taps_.size());
    b_.resize(taps_.size());
    for (const Tap& tap : taps_) weights_.push_back(tap.weight);
    out_.assign(std::size_t(nx), 0.0f);
}

float* CorrelatedNoise::white(long row) {
    const long width = 2 * radius_ + 1;
    return ring_.data() +
           std::size_t(((row % width) + width) % width) * std::size_t(nx_ + 2 * radius_);
}

const float* CorrelatedNoise::row(long row) {
    const long K = radius_;
    require(!started_ || row >= last_row_, "correlated noise: rows must not decrease");
    // White rows row − K … row + K must be in the ring; draw the ones not drawn yet.
    const long from = started_ ? std::max(row - K, last_row_ + K + 1) : row - K;
    for (long r = from; r <= row + K; ++r) white_.row(r, first_ - K, nx_ + 2 * K, white(r));
    last_row_ = row;
    started_ = true;
    // White noise (one central tap of weight 1) is its own row: the sum would copy it (and
    // turn a −0 into +0, the one difference).
    if (taps_.size() == 1 && taps_[0].dx == 0 && taps_[0].dy == 0 && taps_[0].weight == 1.0f)
        return white(row) + K;
    for (std::size_t t = 0; t < taps_.size(); ++t) {
        const Tap& tap = taps_[t];
        a_[t] = white(row + tap.dy) + K + tap.dx;
        b_[t] = tap.paired ? white(row - tap.dy) + K - tap.dx : nullptr;
    }
    const TapRows rows{a_.data(), b_.data(), weights_.data(), taps_.size()};
#ifdef SHAPESIM_LANES_X86
    if (have_avx512()) {
        sum_taps_avx512(rows, nx_, out_.data());
        return out_.data();
    }
#endif
    sum_taps(rows, nx_, out_.data());
    return out_.data();
}

}  // namespace shapesim
