// Counter-based random streams: every random draw in shapesim comes from a stream keyed by
// (run seed, object id, purpose), so one object's realisation does not depend on thread count,
// tile or order (DESIGN §2 "Randomness"): same key and same calls ⇒ bit-identical numbers.
//
// Generator: Philox4x64-10 of Random123 (Salmon, Moraes, Dror & Shaw 2011, "Parallel random
// numbers: as easy as 1, 2, 3", SC'11), a keyed bijection of 256-bit counters. The layout is
// fixed (changing it changes every simulation, so it is pinned by tests):
//   key     = (run seed, object id)
//   counter = (block, purpose, 0, 0)          block = 0, 1, 2, …; the last two words reserved
// Each block gives four 64-bit words, used in order. String ids and purposes are hashed with
// 64-bit FNV-1a over their bytes (offset basis 0xcbf29ce484222325, prime 0x100000001b3; Fowler,
// Noll & Vo, IETF draft-eastlake-fnv). An integer id is used as it is, so the string "7" and the
// integer 7 are different objects: a catalogue must keep one form per id field.
//
// Words consumed by each draw (part of the contract, as it fixes which numbers come next):
//   next_u64, uniform*, coin, sign, angle: 1;  gaussian, gaussian_pair: 2 (Box–Muller, both
//   from the same two words; gaussian returns the cosine branch and keeps no spare value);
//   epanechnikov: 3;  uniform_index: 1, or more on the rare rejection (probability < n/2⁶⁴);
//   poisson: 0 for mean 0, 1 for mean < 10 (inversion), 2 per trial for mean ≥ 10 (PTRS,
//   ~1.1–1.2 trials on average).
//
// Distributions:
//   uniform()        k · 2⁻⁵³ with k the top 53 bits of a word: [0, 1), all 2⁵³ values
//   uniform_open()   (k + ½) · 2⁻⁵³: (0, 1), symmetric about ½
//   gaussian()       Box–Muller: √(−2 ln u₁) cos 2πu₂, u₁ = uniform_open, u₂ = uniform
//   poisson(μ)       μ < 10: inversion of the CDF (exact to rounding of the cumulative sum);
//                    μ ≥ 10: Hörmann's transformed rejection with squeeze, PTRS (W. Hörmann,
//                    "The transformed rejection method for generating Poisson random
//                    variables", Insurance: Mathematics and Economics 12, 39, 1993); exact.
//   epanechnikov()   density ¾(1 − x²) on [−1, 1], CDF (2 + 3x − x³)/4, by the paper's rule
//                    (Massey et al. 2004 §4.1): "generating three random numbers from a uniform
//                    probability distribution between −λ and λ. If the first does not have the
//                    highest absolute value, take it and discard the rest; otherwise take the
//                    second" (DESIGN §4) — Devroye (1986, p. 237)'s generator with the variates
//                    relabelled. Ties (probability ~2⁻⁵²) count as "highest". Scale by λ.
#pragma once

#include <array>
#include <cmath>
#include <limits>
#include <cstdint>
#include <string_view>
#include <utility>

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
double log_factorial(double k);
std::uint64_t poisson_inversion(double mean, double u);
void check_poisson_mean(double mean);  ///< throws Error unless 0 ≤ μ ≤ 2⁶², finite
}  // namespace detail

/// Poisson deviate of mean μ from any source of uniform() ∈ [0, 1) and uniform_open() ∈ (0, 1)
/// (RandomStream::poisson's algorithm and word use: inversion below 10, PTRS above).
template <class Source>
std::uint64_t poisson_deviate(double mean, Source& source) {
    detail::check_poisson_mean(mean);
    if (mean == 0.0) return 0;
    if (mean < 10.0) return detail::poisson_inversion(mean, source.uniform());
    // PTRS (Hörmann 1993, §3, with his constants): a transformed-rejection proposal from a
    // hat over the inverse CDF, a squeeze for fast acceptance, and the exact test otherwise.
    // ln μ and 1/α only for the exact test. The squeeze takes 0.86 (0.9277 − 3.6224/(b − 2))
    // of draws without them: 35% at μ = 10, 59% of the HDF scene's draws of μ ≥ 10, 86% as
    // μ → ∞.
    const double root = std::sqrt(mean);
    const double b = 0.931 + 2.53 * root;
    const double a = -0.059 + 0.02483 * b;
    const double v_r = 0.9277 - 3.6224 / (b - 2.0);
    for (;;) {
        const double u = source.uniform_open() - 0.5;  // (−½, ½): us > 0 below
        const double v = source.uniform_open();        // (0, 1): log v finite
        const double us = 0.5 - std::abs(u);
        const double k = std::floor((2.0 * a / us + b) * u + mean + 0.43);
        if (us >= 0.07 && v <= v_r) return std::uint64_t(k);
        if (k < 0.0 || (us < 0.013 && v > us)) continue;
        const double inv_alpha = 1.1239 + 1.1328 / (b - 3.4);
        const double log_hat = std::log(v * inv_alpha / (a / (us * us) + b));
        if (log_hat <= -mean + k * std::log(mean) - detail::log_factorial(k)) return std::uint64_t(k);
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
    /// |deviate| for an abscissa x ∈ [x_{layer+1}, x_layer) outside its layer's rectangle: the
    /// wedge or tail test, drawing what it needs from `more`.
    double finish(int layer, double x, RandomStream& more) const { return slow(layer, x, more); }
    static const Ziggurat& instance();

private:
    Ziggurat();
    double slow(int layer, double x, RandomStream& more) const;
    double x_[129];  ///< x_[0]: base-layer width V/f(R); x_[1] = R; x_[128] = 0
    double f_[129];  ///< e^{−x²/2} at x_[i] (f_[0] unused)
};

}  // namespace shapesim
