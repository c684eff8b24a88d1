// Counter-based random streams: every random draw in shapesim comes from a stream keyed by
// (run seed, object id, purpose), so one object's realisation does not depend on thread count,
// tile or order (DESIGN §2 "Randomness"): same key and same calls ⇒ bit-identical numbers.
// Generator: Philox4x64-10 of Random123 (Salmon et al. 2011); key = (run seed, object id),
// counter = (block, purpose, 0, 0); string ids and purposes hashed by 64-bit FNV-1a. The
// layout, the words each draw consumes and each distribution's recipe are fixed (changing
// them changes every simulation; tests pin them).
// Derivation: docs/algorithms.md#random-streams
#pragma once

#include <array>
#include <cmath>
#include <limits>
#include <cstdint>
#include <string_view>
#include <type_traits>
#include <utility>

#include "shapesim/lane_math.hpp"

namespace shapesim {

/// 64-bit FNV-1a hash of the bytes of `text` (the fixed hash of string ids and purposes).
constexpr std::uint64_t fnv1a_64(std::string_view text) {
    std::uint64_t hash = 0xcbf29ce484222325ULL;
    for (const char c : text) {
        hash ^= static_cast<unsigned char>(c);
        hash *= 0x100000001b3ULL;
    }
    return hash;
}

/// One Philox4x64-10 block (Random123 names its own macro philox4x64): the raw generator.
std::array<std::uint64_t, 4> philox_block(const std::array<std::uint64_t, 4>& counter,
                                          const std::array<std::uint64_t, 2>& key);

/// A purpose already hashed (fnv1a_64 at compile time), for streams made per pixel.
struct PurposeHash {
    std::uint64_t value;
    constexpr explicit PurposeHash(std::string_view purpose) : value(fnv1a_64(purpose)) {}
};

/// A reproducible random stream for one (run seed, object, purpose). Cheap to construct
/// (no state beyond the key and a position); not shared between threads — make one per use.
class RandomStream {
public:
    /// @param seed the run seed (`--seed`); @param object_id the object's integer id;
    /// @param purpose what the numbers are for ("position", "noise", …; hashed by FNV-1a)
    RandomStream(std::uint64_t seed, std::uint64_t object_id, std::string_view purpose);
    /// The same with the purpose hashed once (a stream per pixel need not hash it each time).
    RandomStream(std::uint64_t seed, std::uint64_t object_id, PurposeHash purpose)
        : key_{seed, object_id}, purpose_(purpose.value) {}
    /// String object id, hashed by FNV-1a (= the integer form with fnv1a_64(object_id)).
    RandomStream(std::uint64_t seed, std::string_view object_id, std::string_view purpose);
    /// The stream of (seed, object_id, purpose) with its first block already computed, as
    /// first_blocks gives it: the same numbers as the stream made alone.
    RandomStream(std::uint64_t seed, std::uint64_t object_id, PurposeHash purpose,
                 const std::array<std::uint64_t, 4>& first_block)
        : key_{seed, object_id}, purpose_(purpose.value), buffered_block_(0),
          buffer_(first_block) {}
    /// The first blocks of the streams (seed, ids[i], purpose), i < n, into out[i]: computed
    /// together, their latencies overlap (one stream per pixel waits on one block each).
    static void first_blocks(std::uint64_t seed, const std::uint64_t* ids, std::size_t n,
                             PurposeHash purpose, std::array<std::uint64_t, 4>* out);

    /// The next raw 64-bit word.
    std::uint64_t next_u64() {
        if ((position_ >> 2) != buffered_block_) refill();
        return buffer_[position_++ & 3];
    }
    /// Words consumed so far; `seek(w)` makes the next word the w-th of the stream (0-based).
    std::uint64_t position() const { return position_; }
    void seek(std::uint64_t word) { position_ = word; }

    /// Uniform on [0, 1) with 53 random bits.
    double uniform() { return double(next_u64() >> 11) * 0x1.0p-53; }
    /// Uniform on (0, 1): never 0 or 1.
    double uniform_open() { return (double(next_u64() >> 11) + 0.5) * 0x1.0p-53; }
    /// Uniform on [lo, hi).
    double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
    /// Uniform integer in [0, n), unbiased (rejection of the top 2⁶⁴ mod n words); n ≥ 1.
    std::uint64_t uniform_index(std::uint64_t n);
    /// Fair coin (the top bit of a word).
    bool coin() { return (next_u64() >> 63) != 0; }
    /// +1 or −1 with equal probability.
    double sign() { return coin() ? 1.0 : -1.0; }
    /// Uniform angle in [0, 2π) radians.
    double angle() { return 6.283185307179586477 * uniform(); }

    /// Standard normal deviate (Box–Muller, 2 words).
    double gaussian() { return gaussian_pair().first; }
    /// Normal deviate with the given mean and standard deviation.
    double gaussian(double mean, double sigma) { return mean + sigma * gaussian(); }
    /// Two independent standard normal deviates from 2 words.
    std::pair<double, double> gaussian_pair();

    /// Poisson deviate of mean μ (finite, 0 ≤ μ ≤ 2⁶²; μ = 0 gives 0); throws Error otherwise.
    std::uint64_t poisson(double mean);

    /// Epanechnikov deviate on [−1, 1] (the paper's three-uniform rule; multiply by λ).
    double epanechnikov();

private:
    void refill();

    std::array<std::uint64_t, 2> key_;
    std::uint64_t purpose_;
    std::uint64_t position_ = 0;
    std::uint64_t buffered_block_ = ~std::uint64_t(0);
    std::array<std::uint64_t, 4> buffer_{};
};

namespace detail {

std::uint64_t poisson_inversion(double mean, double u);
void check_poisson_mean(double mean);  ///< throws Error unless 0 ≤ μ ≤ 2⁶², finite

/// 1/k for the inversion's steps: a multiply instead of a division on the loop's critical path.
struct Reciprocals {
    double value[64] = {};
    constexpr Reciprocals() {
        for (int k = 1; k < 64; ++k) value[k] = 1.0 / k;
    }
};
inline constexpr Reciprocals reciprocals{};  // constant-initialised: no static-order hazard

// The templates below take lanes (lane_math.hpp's four-double vectors) as well as doubles.

/// ln k! for k = 0 … 20: lane::log of the exact product.
const double* small_log_factorials();

/// ln k! for integral k ≥ 0 (lanes with k < 0 give garbage): the table up to 20!, then
/// Stirling's series for ln Γ(k + 1) with terms to x⁻⁷ (the next term is < 1/(1188 x⁹) <
/// 1e-15 for x ≥ 21). Thread-safe and libm-free (std::lgamma writes the global signgam).
template <class D>
SHAPESIM_LANES D log_factorial(D k, const double* small) {
    if constexpr (std::is_same_v<D, double>)
        if (k <= 20.0) return small[int(k)];
    const D x = k + 1.0, inv = 1.0 / x, inv2 = inv * inv;
    const D series = inv * (1.0 / 12 - inv2 * (1.0 / 360 - inv2 * (1.0 / 1260 - inv2 / 1680)));
    D out = (x - 0.5) * lane::log(x) - x + 0.91893853320467274178 + series;  // ½ ln 2π
    if constexpr (!std::is_same_v<D, double>) {
        // The table's entries, made into lanes from scalars and chosen by a mask: lanes
        // written one by one would go through memory, and the vector read back after those
        // scalar writes waits for them.
        static_assert(sizeof(D) == 4 * sizeof(double), "four lanes");
        auto entry = [&](int i) { return k[i] >= 0.0 && k[i] <= 20.0 ? small[int(k[i])] : 0.0; };
        const D table = {entry(0), entry(1), entry(2), entry(3)};
        out = ((k >= 0.0) & (k <= 20.0)) ? table : out;
    }
    return out;
}
inline double log_factorial(double k) { return log_factorial(k, small_log_factorials()); }

/// PTRS (Hörmann 1993, §3, with his constants) for mean μ ≥ 10: a transformed-rejection
/// proposal k from a hat over the inverse CDF, a squeeze for fast acceptance, and the exact
/// test otherwise. Written for a double or for lanes (lane_math.hpp), one home for both.
template <class D>
struct Ptrs {
    D mean, b, a, v_r;
    SHAPESIM_LANES explicit Ptrs(D mu)
        : mean(mu), b(0.931 + 2.53 * lane::sqrt(mu)), a(-0.059 + 0.02483 * b),
          v_r(0.9277 - 3.6224 / (b - 2.0)) {}
    /// The proposal of u ∈ (−½, ½); `us` = ½ − |u| > 0.
    SHAPESIM_LANES D proposal(D u, D& us) const {
        us = 0.5 - lane::abs(u);
        return lane::floor((2.0 * a / us + b) * u + mean + 0.43);
    }
    /// The squeeze: accepted without logs (0.86 (0.9277 − 3.6224/(b − 2)) of draws: 35% at
    /// μ = 10, 59% of the HDF scene's draws of μ ≥ 10, 86% as μ → ∞).
    SHAPESIM_LANES auto squeezed(D us, D v) const { return (us >= 0.07) & (v <= v_r); }
    /// Rejected without logs.
    SHAPESIM_LANES auto rejected(D k, D us, D v) const {
        return (k < 0.0) | ((us < 0.013) & (v > us));
    }
    /// The exact test (k ≥ 0).
    SHAPESIM_LANES auto exact(D k, D us, D v, const double* small) const {
        const D inv_alpha = 1.1239 + 1.1328 / (b - 3.4);
        const D log_hat = lane::log(v * inv_alpha / (a / (us * us) + b));
        return log_hat <= -mean + k * lane::log(mean) - log_factorial(k, small);
    }
    /// One trial with uniforms u ∈ (−½, ½), v ∈ (0, 1): true and k when accepted.
    bool trial(double u, double v, double& k, const double* small) const {
        double us;
        k = proposal(u, us);
        if (squeezed(us, v)) return true;
        if (rejected(k, us, v)) return false;
        return exact(k, us, v, small);
    }
};

}  // namespace detail

/// Poisson deviate of mean μ from any source of uniform() ∈ [0, 1) and uniform_open() ∈ (0, 1)
/// (RandomStream::poisson's algorithm and word use: inversion below 10, PTRS above).
template <class Source>
std::uint64_t poisson_deviate(double mean, Source& source) {
    detail::check_poisson_mean(mean);
    if (mean == 0.0) return 0;
    if (mean < 10.0) return detail::poisson_inversion(mean, source.uniform());
    const detail::Ptrs<double> ptrs(mean);
    const double* small = detail::small_log_factorials();
    for (double k;;) {
        const double u = source.uniform_open() - 0.5;  // (−½, ½): us > 0
        const double v = source.uniform_open();        // (0, 1): ln v finite
        if (ptrs.trial(u, v, k, small)) return std::uint64_t(k);
    }
}

/// Standard normal deviates by the ziggurat (Marsaglia & Tsang 2000; 128 layers, R =
/// 3.442619855899, layer area V = 9.91256303526217e-3), one 64-bit word per deviate: 7 bits
/// pick the layer, 1 the sign, 53 the abscissa. The word alone decides 97.3% of the time; the
/// wedge and tail tests draw what they need from `more()`, a RandomStream& the caller supplies
/// (called only then). With a word fixed per pixel and `more` keyed by the pixel, noise is a
/// pure function of the pixel — the same in any tile — at a few ns per deviate.
class Ziggurat {
public:
    template <class More>
    double operator()(std::uint64_t word, More&& more) const {
        const int layer = int(word & 127);
        const double sign = (word & 128) ? -1.0 : 1.0;
        const double x = double(word >> 11) * 0x1.0p-53 * x_[layer];  // u ∈ [0, 1) × width
        if (x < x_[layer + 1]) return sign * x;  // wholly under the curve
        return sign * slow(layer, x, more());
    }
    /// x_i, the layers' edges: x_0 the base layer's width V/f(R), x_1 = R, x_128 = 0 (for
    /// other word layouts, as pixel_noise.hpp's single-precision one).
    double edge(int i) const { return x_[i]; }
    /// e^{−x_i²/2} (f_0 unused).
    double density(int i) const { return f_[i]; }
    static constexpr double tail_start = 3.442619855899;  ///< R = x_1
    /// |deviate| for an abscissa x ∈ [x_{layer+1}, x_layer) outside its layer's rectangle: the
    /// wedge or tail test, drawing what it needs from `more` (ln and e^x from lane_math.hpp,
    /// so that lanes can do the same: pixel_noise.cpp).
    double finish(int layer, double x, RandomStream& more) const { return slow(layer, x, more); }
    static const Ziggurat& instance();

private:
    Ziggurat();
    double slow(int layer, double x, RandomStream& more) const;
    double x_[129];  ///< x_[0]: base-layer width V/f(R); x_[1] = R; x_[128] = 0
    double f_[129];  ///< e^{−x²/2} at x_[i] (f_[0] unused)
};

}  // namespace shapesim
