// Photon noise keyed by the field pixel (pixel_noise.hpp): Poisson deviates four pixels at a
// time in lanes, the rejected PTRS trials settled per row.
#include "shapesim/pixel_noise.hpp"

#include "shapesim/error.hpp"
#include "shapesim/lane_math.hpp"
#include "shapesim/rng.hpp"

#include <algorithm>
#include <array>
#include <cstring>
#include <vector>

namespace shapesim {

namespace {

using lane::Doubles4;
using lane::have_avx2;
using lane::Mask4;
using lane::top53;
using lane::Words4;

SHAPESIM_LANES bool any(Mask4 m) {
    const Mask4 halves = m | __builtin_shufflevector(m, m, 2, 3, 0, 1);
    return (halves[0] | halves[1]) != 0;
}

SHAPESIM_LANES Mask4 real_lanes(int lanes) { return Mask4{0, 1, 2, 3} < lanes; }

// PTRS's trial (detail::Ptrs::trial) in each lane of `active`: the lanes accepted, and the
// proposals in k.
SHAPESIM_LANES Mask4 ptrs_trial(const detail::Ptrs<Doubles4>& ptrs, Doubles4 u, Doubles4 v,
                                Mask4 active, const double* small, Doubles4& k) {
    Doubles4 us;
    k = ptrs.proposal(u, us);
    Mask4 open = active & ~ptrs.squeezed(us, v);
    if (any(open)) {
        const Mask4 candidates = open & ~ptrs.rejected(k, us, v);
        if (any(candidates)) open &= ~(candidates & ptrs.exact(k, us, v, small));
    }
    return active & ~open;
}

// A run of n pixels bright enough, whose Philox4x32 blocks are words[4i … 4i + 3]: each pixel
// replaced by its photon-noise draw, four at a time in lanes. Every lane does what
// poisson_deviate does for one pixel with the pixel's block (words 0–1, then 2–3) — the same
// operations on the same numbers (lane_math.hpp), so the same bits: inversion below 10, PTRS's
// first trial above. A pixel whose first trial is rejected is listed (its index from `offset`
// and its mean) for settle_open, which finishes it from its own stream.
__attribute__((always_inline)) inline void photon_run(const std::uint32_t* words, long n,
                                                      double gain, double* pixels, long offset,
                                                      std::vector<long>& open_pixels,
                                                      std::vector<double>& open_means) {
    const double* small = detail::small_log_factorials();
    for (long i = 0; i < n; i += 4) {
        // Four pixels and their blocks; past the run's end, padding lanes of mean 10.
        const int lanes = int(std::min(4L, n - i));
        Doubles4 mean = {10.0, 10.0, 10.0, 10.0};
        std::uint32_t block[16] = {};
        if (lanes == 4) {
            std::memcpy(&mean, pixels + i, sizeof mean);
            std::memcpy(block, words + 4 * i, sizeof block);
        } else {
            for (int j = 0; j < lanes; ++j) mean[j] = pixels[i + j];
            std::memcpy(block, words + 4 * i, 4 * sizeof(std::uint32_t) * std::size_t(lanes));
        }
        mean = real_lanes(lanes) ? mean * gain : mean;
        if (any(~((mean >= 0.0) & (mean <= 0x1.0p62))))
            for (int j = 0; j < lanes; ++j) detail::check_poisson_mean(mean[j]);  // throws
        Words4 low_half, high_half;  // pixels 0–1's words 0–3, pixels 2–3's
        std::memcpy(&low_half, block, sizeof low_half);
        std::memcpy(&high_half, block + 8, sizeof high_half);
        const Doubles4 top1 = top53(__builtin_shufflevector(low_half, high_half, 0, 2, 4, 6));
        const Doubles4 top2 = top53(__builtin_shufflevector(low_half, high_half, 1, 3, 5, 7));
        const Mask4 real = real_lanes(lanes);
        const Mask4 inversion = real & (mean > 0.0) & (mean < 10.0);
        const Mask4 ptrs_lanes = real & (mean >= 10.0);
        Doubles4 count = {0.0, 0.0, 0.0, 0.0};
        if (any(inversion)) {
            // detail::poisson_inversion lane by lane: walk the CDF until u ≤ it.
            const Doubles4 mu = inversion ? mean : 1.0;
            const Doubles4 u = top1 * 0x1.0p-53;  // uniform()
            // A lane that has stopped keeps stepping p and cdf (values no one reads), so the
            // steps do not wait on the comparisons; and the lanes are asked whether any still
            // walks only every fourth step (the walk's length is random: a test per step
            // mispredicts its last, and each group of pixels pays that).
            Doubles4 p = lane::exp(-mu), cdf = p;
            Mask4 walking = inversion & (u > cdf);
            for (long k = 1; any(walking);)
                for (const long last = k + 4; k < last; ++k) {
                    p = p * (k < 64 ? mu * detail::reciprocals.value[k] : mu / double(k));
                    const Mask4 far = p < 1e-300;  // the far tail: stop there
                    count = walking ? double(k) : count;
                    cdf = cdf + p;
                    walking = walking & ~far & (u > cdf);
                }
        }
        if (any(ptrs_lanes)) {
            const detail::Ptrs<Doubles4> ptrs(ptrs_lanes ? mean : 10.0);
            const Doubles4 u = (top1 + 0.5) * 0x1.0p-53 - 0.5;  // uniform_open() − ½
            const Doubles4 v = (top2 + 0.5) * 0x1.0p-53;        // uniform_open()
            Doubles4 k;
            const Mask4 open = ptrs_lanes & ~ptrs_trial(ptrs, u, v, ptrs_lanes, small, k);
            count = ptrs_lanes ? k : count;
            if (any(open))  // first trials rejected: the next ones from the pixel's own stream
                for (int j = 0; j < lanes; ++j)
                    if (open[j]) {
                        open_pixels.push_back(offset + i + j);
                        open_means.push_back(mean[j]);
                    }
        }
        count /= gain;
        if (lanes == 4)
            std::memcpy(pixels + i, &count, sizeof count);
        else
            for (int j = 0; j < lanes; ++j) pixels[i + j] = count[j];
    }
}

// The pixels photon_run listed (pixels[index[k]] of mean[k], k < n; blocks[k] the first
// block of the pixel's stream RandomStream(seed, key, "photon noise more")): PTRS's second and
// third trials from the block's words 0–1 and 2–3 in lanes, as poisson_deviate takes them; the
// rare pixel still open, one at a time from word 4 of its stream.
__attribute__((always_inline)) inline void settle_open(const long* index, const double* mean_of,
                                                      const std::array<std::uint64_t, 4>* blocks,
                                                      const std::uint64_t* keys, long n,
                                                      double gain, double* pixels,
                                                      std::uint64_t seed) {
    static constexpr PurposeHash more_purpose("photon noise more");
    const double* small = detail::small_log_factorials();
    for (long i = 0; i < n; i += 4) {
        const int lanes = int(std::min(4L, n - i));
        // Lanes made from scalars (past the end, copies of the last pixel), not written one
        // by one: a vector read after lane-by-lane writes waits for them.
        const auto p = [&](int j) { return std::size_t(i + std::min(j, lanes - 1)); };
        const Doubles4 mean = {mean_of[p(0)], mean_of[p(1)], mean_of[p(2)], mean_of[p(3)]};
        Words4 w[4];
        for (std::size_t q = 0; q < 4; ++q)
            w[q] = Words4{blocks[p(0)][q], blocks[p(1)][q], blocks[p(2)][q], blocks[p(3)][q]};
        const Mask4 real = real_lanes(lanes);
        const detail::Ptrs<Doubles4> ptrs(mean);
        Doubles4 count = {0.0, 0.0, 0.0, 0.0}, k;
        Mask4 open = real;
        for (int trial = 0; trial < 2 && any(open); ++trial) {
            const Doubles4 u = (top53(w[2 * trial]) + 0.5) * 0x1.0p-53 - 0.5;
            const Doubles4 v = (top53(w[2 * trial + 1]) + 0.5) * 0x1.0p-53;
            const Mask4 accepted = ptrs_trial(ptrs, u, v, open, small, k);
            count = accepted ? k : count;
            open &= ~accepted;
        }
        if (any(open))
            for (int j = 0; j < lanes; ++j) {
                if (!open[j]) continue;
                RandomStream more(seed, keys[i + j], more_purpose);
                more.seek(4);
                const detail::Ptrs<double> one(mean[j]);
                double kj;
                for (;;) {
                    const double uj = more.uniform_open() - 0.5, vj = more.uniform_open();
                    if (one.trial(uj, vj, kj, small)) break;
                }
                count[j] = kj;
            }
        count /= gain;
        for (int j = 0; j < lanes; ++j) pixels[index[i + j]] = count[j];
    }
}

// photon_run and settle_open compiled for AVX2 and for the baseline, chosen as the generators
// are (SHAPESIM_SIMD=none takes the baseline: the program tests compare the bytes).
#ifdef SHAPESIM_LANES_X86
__attribute__((target("avx2"))) void photon_run_avx2(const std::uint32_t* words, long n,
                                                     double gain, double* pixels, long offset,
                                                     std::vector<long>& open_pixels,
                                                     std::vector<double>& open_means) {
    photon_run(words, n, gain, pixels, offset, open_pixels, open_means);
}
__attribute__((target("avx2"))) void settle_open_avx2(const long* index, const double* mean,
                                                      const std::array<std::uint64_t, 4>* blocks,
                                                      const std::uint64_t* keys, long n,
                                                      double gain, double* pixels,
                                                      std::uint64_t seed) {
    settle_open(index, mean, blocks, keys, n, gain, pixels, seed);
}
#endif
void photon_run_baseline(const std::uint32_t* words, long n, double gain, double* pixels,
                         long offset, std::vector<long>& open_pixels,
                         std::vector<double>& open_means) {
    photon_run(words, n, gain, pixels, offset, open_pixels, open_means);
}
void settle_open_baseline(const long* index, const double* mean,
                          const std::array<std::uint64_t, 4>* blocks, const std::uint64_t* keys,
                          long n, double gain, double* pixels, std::uint64_t seed) {
    settle_open(index, mean, blocks, keys, n, gain, pixels, seed);
}

// The first i in [from, count) whose pixel is bright enough for photon noise (s > 0 and
// s ≥ least) when `bright`, or is not when !bright; count if there is none. Most of an image is
// dark sky, scanned here: eight pixels a step in AVX2, their tests as a bit mask whose lowest
// set bit is the answer.
long next_bright_scalar(const double* pixels, long from, long count, double least, bool bright) {
    for (long i = from; i < count; ++i)
        if ((pixels[i] > 0.0 && pixels[i] >= least) == bright) return i;
    return count;
}

#ifdef SHAPESIM_LANES_X86
// Bit k set where pixel k of the four at `s` is bright (NaN is not).
__attribute__((target("avx2"))) inline unsigned bright_bits(const double* s, __m256d least) {
    const __m256d v = _mm256_loadu_pd(s);
    return unsigned(_mm256_movemask_pd(_mm256_and_pd(
        _mm256_cmp_pd(v, _mm256_setzero_pd(), _CMP_GT_OQ), _mm256_cmp_pd(v, least, _CMP_GE_OQ))));
}

__attribute__((target("avx2"))) long next_bright_avx2(const double* pixels, long from, long count,
                                                      double least, bool bright) {
    const __m256d least_lanes = _mm256_set1_pd(least);
    const unsigned flip = bright ? 0u : 0xffu;
    long i = from;
    for (; i + 8 <= count; i += 8)
        if (const unsigned wanted = (bright_bits(pixels + i, least_lanes) |
                                     bright_bits(pixels + i + 4, least_lanes) << 4) ^
                                    flip;
            wanted != 0) {
            _mm256_zeroupper();
            return i + __builtin_ctz(wanted);
        }
    _mm256_zeroupper();
    return next_bright_scalar(pixels, i, count, least, bright);
}
#endif

long next_bright(const double* pixels, long from, long count, double least, bool bright) {
#ifdef SHAPESIM_LANES_X86
    if (have_avx2()) return next_bright_avx2(pixels, from, count, least, bright);
#endif
    return next_bright_scalar(pixels, from, count, least, bright);
}

}  // namespace

void PhotonNoise::row(long row, long first, long count, double gain, double least,
                      double* pixels) const {
    require(row >= 0 && first >= 0 && row + WhiteNoise::margin < (1L << 32) &&
                first + count + WhiteNoise::margin <= (1L << 32),
            "photon noise: pixel outside the keyed range");
    constexpr std::uint64_t purpose = fnv1a_64("photon noise");
    const std::uint64_t row_key = std::uint64_t(row + WhiteNoise::margin) << 32;
    // Runs of pixels bright enough, each run's blocks drawn together; then the row's pixels
    // whose first trial was rejected, their streams' first blocks computed together.
    open_pixels_.clear();
    open_means_.clear();
    for (long i0 = next_bright(pixels, 0, count, least, true); i0 < count;) {
        const long i1 = next_bright(pixels, i0 + 1, count, least, false);
        const std::uint64_t q0 = std::uint64_t(first + i0 + WhiteNoise::margin);
        words_.resize(4 * std::size_t(i1 - i0));
        philox4x32_blocks(seed_, std::uint32_t(q0), std::uint32_t(row + WhiteNoise::margin),
                          std::uint32_t(purpose), std::uint32_t(purpose >> 32),
                          std::size_t(i1 - i0), words_.data());
#ifdef SHAPESIM_LANES_X86
        if (have_avx2())
            photon_run_avx2(words_.data(), i1 - i0, gain, pixels + i0, i0, open_pixels_,
                            open_means_);
        else
#endif
            photon_run_baseline(words_.data(), i1 - i0, gain, pixels + i0, i0, open_pixels_,
                                open_means_);
        i0 = next_bright(pixels, i1, count, least, true);
    }
    const std::size_t open = open_pixels_.size();
    if (open == 0) return;
    static constexpr PurposeHash more_purpose("photon noise more");
    keys_.resize(open);
    blocks_.resize(open);
    const std::uint64_t key0 = row_key + std::uint64_t(first + WhiteNoise::margin);
    for (std::size_t k = 0; k < open; ++k) keys_[k] = key0 + std::uint64_t(open_pixels_[k]);
    RandomStream::first_blocks(seed_, keys_.data(), open, more_purpose, blocks_.data());
#ifdef SHAPESIM_LANES_X86
    if (have_avx2())
        settle_open_avx2(open_pixels_.data(), open_means_.data(), blocks_.data(), keys_.data(),
                         long(open), gain, pixels, seed_);
    else
#endif
        settle_open_baseline(open_pixels_.data(), open_means_.data(), blocks_.data(),
                             keys_.data(), long(open), gain, pixels, seed_);
}

}  // namespace shapesim
