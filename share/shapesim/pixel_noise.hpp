// The background noise of a simulated field, keyed by the field pixel so that any tile or
// thread draws the same numbers (DESIGN §2 "Randomness"; issue 16: near the floor of the
// machine).
//
// White noise (WhiteNoise): the standard normal deviate of field pixel (row R, column C),
// 0-based, −64 ≤ R, C < 2³² − 64, is the ziggurat (rng.hpp) of one 32-bit word of
// Philox4x32-10 (Salmon et al. 2011; the same generator as Random123's r123::Philox4x32):
//   key     = (seed mod 2³², ⌊seed / 2³²⌋)
//   counter = (⌊(C + 64) / 4⌋, R + 64, P mod 2³², ⌊P / 2³²⌋),  P = FNV-1a 64 of "white noise"
//   word    = (C + 64) mod 4 of the block
// The word's low 7 bits pick the layer, bit 7 the sign, the top 24 bits the abscissa, times the
// layer's width in single precision (the noise is written as 32-bit floats). 97.3% of words
// decide alone; the rest (the wedge and tail tests, Ziggurat::finish) draw from
// RandomStream(seed, (R + 64)·2³² + C + 64, "white noise retry"): those streams' first blocks
// computed together, their first two words' tests in lanes (~99% settle there), the others one
// at a time. With AVX-512 or
// AVX2 (the widest the CPU has; SHAPESIM_SIMD=avx2 or none asks for narrower) blocks are computed
// sixteen or eight at a time and words turned into deviates as many at a time (AVX-512 looks the
// layer tables up in registers, AVX2 gathers them); otherwise one at a time (Random123's own
// code). Integer arithmetic and one rounded
// single-precision multiply per deviate, so every machine gives the same bits.
//
// Correlated noise (CorrelatedNoise): white noise through a kernel k (noise.hpp; Σk² = 1):
// n(p) = Σ_d k(d) w(p + d) (the same law as the convolution: ξ is symmetric), summed directly in single precision over the taps in a
// fixed order, pairing k(d) with k(−d) when they are equal (every kernel noise.hpp builds is
// point-symmetric), so the cost is about (2K + 1)²/2 multiplies and (2K + 1)² adds per pixel,
// sixteen pixels at a time with AVX-512 (four sums at once where there are 16 taps or more),
// eight with AVX2. Each pixel's sum runs over the same white values in the same order
// whatever the window, so tiles and threads are bit-identical.
#pragma once

#include "shapesim/noise.hpp"

#include <array>
#include <cstdint>
#include <vector>

namespace shapesim {

/// `count` Philox4x32-10 blocks with counters (first + b, c1, c2, c3), b = 0 … count − 1,
/// under `key` (low word first): out[4b + w] = word w of block b.
void philox4x32_blocks(std::uint64_t key, std::uint32_t first, std::uint32_t c1,
                       std::uint32_t c2, std::uint32_t c3, std::size_t count, std::uint32_t* out);

/// The white noise of a seed (see the header comment).
class WhiteNoise {
public:
    static constexpr long margin = 64;  ///< rows and columns from −margin are keyed
    explicit WhiteNoise(std::uint64_t seed) : seed_(seed) {}
    /// Deviates of field row `row`, columns first … first + count − 1, into out[0 … count).
    void row(long row, long first, long count, float* out) const;

private:
    std::uint64_t seed_;
    mutable std::vector<std::uint32_t> words_;
    mutable std::vector<long> slow_;
    mutable std::vector<std::uint64_t> ids_;                  ///< the slow pixels' stream ids
    mutable std::vector<std::array<std::uint64_t, 4>> blocks_;  ///< and their first blocks
};

/// Photon noise keyed by the field pixel: pixel (R, C) ≥ 0 of signal s (image units) becomes
/// N/gain, N ~ Poisson(s · gain) (poisson_deviate), from the two 64-bit words of its
/// Philox4x32-10 block (key as WhiteNoise; counter (C + 64, R + 64, P mod 2³², ⌊P / 2³²⌋),
/// P = FNV-1a 64 of "photon noise"; words 0–1 then 2–3, low first), then, for the rare deviate
/// that needs more, RandomStream(seed, (R + 64)·2³² + C + 64, "photon noise more"). Drawn four
/// pixels at a time in lanes whose ln and exp (lane_math.hpp) give the scalar draw's bits; a
/// row's deviates that need their stream are settled together (the streams' first blocks at
/// once, their next two trials in lanes, the rare rest one at a time).
class PhotonNoise {
public:
    explicit PhotonNoise(std::uint64_t seed) : seed_(seed) {}
    /// Field row `row`, columns first … first + count − 1: every pixel with s > 0 and
    /// s ≥ `least` (where photon noise is worth drawing) replaced by its photon-noise draw.
    void row(long row, long first, long count, double gain, double least, double* pixels) const;

private:
    std::uint64_t seed_;
    mutable std::vector<std::uint32_t> words_;
    // A row's pixels whose first PTRS trial was rejected: index, mean, stream key, first block.
    mutable std::vector<long> open_pixels_;
    mutable std::vector<double> open_means_;
    mutable std::vector<std::uint64_t> keys_;
    mutable std::vector<std::array<std::uint64_t, 4>> blocks_;
};

/// Rows of correlated noise over columns first … first + nx − 1 of the field, in increasing
/// row order (a ring of 2K + 1 white rows: each white row is drawn once).
class CorrelatedNoise {
public:
    CorrelatedNoise(const NoiseKernel& kernel, std::uint64_t seed, long first, long nx);
    /// The noise of field row `row` (rows must not decrease between calls); nx values, valid
    /// until the next call.
    const float* row(long row);
    int radius() const { return radius_; }

private:
    struct Tap {
        float weight;
        int dx, dy;       ///< k(dx, dy) multiplies w(p − d)
        bool paired;      ///< also w(p + d): k(−d) = k(d)
    };
    float* white(long row);  ///< ring slot of white row `row` (columns first − K … first + nx + K − 1)

    WhiteNoise white_;
    int radius_;
    long first_, nx_;
    std::vector<Tap> taps_;
    std::vector<float> ring_, out_, weights_;
    std::vector<const float*> a_, b_;  ///< per tap, this row's white rows (see sum_taps)
    long last_row_ = 0;  ///< white rows last_row_ − K … last_row_ + K are in the ring
    bool started_ = false;
};

}  // namespace shapesim
