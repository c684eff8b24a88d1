// The background and photon noise of a simulated field, keyed by the field pixel, so that any
// tile, thread count or SIMD width draws the same bits (DESIGN §2 "Randomness"): white noise is
// the single-precision ziggurat of one Philox4x32-10 word per pixel (philox.hpp), correlated
// noise white noise through a kernel (noise.hpp) summed directly, photon noise a Poisson
// deviate from the pixel's own block. Which words and bits each draw takes, and in what order:
// docs/library.md, "The pixel noise, bit by bit".
#pragma once

#include "shapesim/noise.hpp"
#include "shapesim/philox.hpp"

#include <array>
#include <cstdint>
#include <vector>

namespace shapesim {

/// The white noise of a seed (docs/library.md, "The pixel noise, bit by bit").
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
    /// The ring slot of white row `row` (columns first − K … first + nx + K − 1).
    float* white(long row);

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
