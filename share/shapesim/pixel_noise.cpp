#include "shapesim/pixel_noise.hpp"

#include "shapesim/error.hpp"
#include "shapesim/lane_math.hpp"
#include "shapesim/rng.hpp"

#include <Random123/philox.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <vector>

#if defined(__x86_64__)
#include <immintrin.h>
#define SHAPESIM_PHILOX_SIMD 1
#endif

// Lanes (lane_math.hpp) pass by value to always-inlined helpers; GCC still warns, at each call
// built without AVX, that AVX code would pass them differently (none is ever out of line).
#pragma GCC diagnostic ignored "-Wpsabi"

namespace shapesim {

namespace {

// Random123's constants for Philox4x32: the multipliers and the Weyl key increments.
constexpr std::uint32_t kM0 = 0xD2511F53u, kM1 = 0xCD9E8D57u;
constexpr std::uint32_t kW0 = 0x9E3779B9u, kW1 = 0xBB67AE85u;

void philox_scalar(std::uint64_t key, std::uint32_t first, std::uint32_t c1, std::uint32_t c2,
                   std::uint32_t c3, std::size_t count, std::uint32_t* out) {
    const r123::Philox4x32::key_type k = {{std::uint32_t(key), std::uint32_t(key >> 32)}};
    for (std::size_t b = 0; b < count; ++b) {
        const r123::Philox4x32::ctr_type c = {{std::uint32_t(first + b), c1, c2, c3}};
        const r123::Philox4x32::ctr_type r = r123::Philox4x32()(c, k);
        std::memcpy(out + 4 * b, r.v, 16);
    }
}

#ifdef SHAPESIM_PHILOX_SIMD
// Eight blocks at once, lane b holding block first + b: (hi, lo) = m · a per 32-bit lane.
__attribute__((target("avx2"))) inline void mulhilo8(__m256i a, __m256i m, __m256i& hi, __m256i& lo) {
    const __m256i even = _mm256_mul_epu32(a, m);
    const __m256i odd = _mm256_mul_epu32(_mm256_srli_epi64(a, 32), m);
    lo = _mm256_blend_epi32(even, _mm256_slli_epi64(odd, 32), 0xAA);
    hi = _mm256_blend_epi32(_mm256_srli_epi64(even, 32), odd, 0xAA);
}

__attribute__((target("avx2"))) std::size_t philox_avx2(std::uint64_t key, std::uint32_t first,
                                                       std::uint32_t c1, std::uint32_t c2,
                                                       std::uint32_t c3, std::size_t count,
                                                       std::uint32_t* out) {
    const __m256i m0 = _mm256_set1_epi32(int(kM0)), m1 = _mm256_set1_epi32(int(kM1));
    const __m256i lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    std::size_t b = 0;
    for (; b + 8 <= count; b += 8) {
        __m256i x0 = _mm256_add_epi32(_mm256_set1_epi32(int(first + std::uint32_t(b))), lanes);
        __m256i x1 = _mm256_set1_epi32(int(c1)), x2 = _mm256_set1_epi32(int(c2));
        __m256i x3 = _mm256_set1_epi32(int(c3));
        std::uint32_t k0 = std::uint32_t(key), k1 = std::uint32_t(key >> 32);
        for (int round = 0; round < 10; ++round) {
            if (round > 0) k0 += kW0, k1 += kW1;
            __m256i hi0, lo0, hi1, lo1;
            mulhilo8(x0, m0, hi0, lo0);
            mulhilo8(x2, m1, hi1, lo1);
            x0 = _mm256_xor_si256(_mm256_xor_si256(hi1, x1), _mm256_set1_epi32(int(k0)));
            x1 = lo1;
            x2 = _mm256_xor_si256(_mm256_xor_si256(hi0, x3), _mm256_set1_epi32(int(k1)));
            x3 = lo0;
        }
        // Lanes are blocks, registers words: transpose to block-major, per 128-bit half (the
        // low half holds blocks b … b + 3, the high half b + 4 … b + 7).
        const __m256i t0 = _mm256_unpacklo_epi32(x0, x1), t1 = _mm256_unpacklo_epi32(x2, x3);
        const __m256i t2 = _mm256_unpackhi_epi32(x0, x1), t3 = _mm256_unpackhi_epi32(x2, x3);
        const __m256i s0 = _mm256_unpacklo_epi64(t0, t1), s1 = _mm256_unpackhi_epi64(t0, t1);
        const __m256i s2 = _mm256_unpacklo_epi64(t2, t3), s3 = _mm256_unpackhi_epi64(t2, t3);
        __m256i* o = reinterpret_cast<__m256i*>(out + 4 * b);
        _mm256_storeu_si256(o + 0, _mm256_permute2x128_si256(s0, s1, 0x20));
        _mm256_storeu_si256(o + 1, _mm256_permute2x128_si256(s2, s3, 0x20));
        _mm256_storeu_si256(o + 2, _mm256_permute2x128_si256(s0, s1, 0x31));
        _mm256_storeu_si256(o + 3, _mm256_permute2x128_si256(s2, s3, 0x31));
    }
    return b;
}

// Sixteen blocks at once, as philox_avx2 does eight. (GCC 12's AVX-512 intrinsics start from
// _mm512_undefined_*: a false "may be used uninitialized", GCC bug 105593.)
#pragma GCC diagnostic push
#ifndef __clang__
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
__attribute__((target("avx512f"))) inline void mulhilo16(__m512i a, __m512i m, __m512i& hi, __m512i& lo) {
    const __m512i even = _mm512_mul_epu32(a, m);
    const __m512i odd = _mm512_mul_epu32(_mm512_srli_epi64(a, 32), m);
    lo = _mm512_mask_blend_epi32(0xAAAA, even, _mm512_slli_epi64(odd, 32));
    hi = _mm512_mask_blend_epi32(0xAAAA, _mm512_srli_epi64(even, 32), odd);
}

__attribute__((target("avx512f"))) std::size_t philox_avx512(std::uint64_t key, std::uint32_t first,
                                                            std::uint32_t c1, std::uint32_t c2,
                                                            std::uint32_t c3, std::size_t count,
                                                            std::uint32_t* out) {
    const __m512i m0 = _mm512_set1_epi32(int(kM0)), m1 = _mm512_set1_epi32(int(kM1));
    const __m512i lanes = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    std::size_t b = 0;
    for (; b + 16 <= count; b += 16) {
        __m512i x0 = _mm512_add_epi32(_mm512_set1_epi32(int(first + std::uint32_t(b))), lanes);
        __m512i x1 = _mm512_set1_epi32(int(c1)), x2 = _mm512_set1_epi32(int(c2));
        __m512i x3 = _mm512_set1_epi32(int(c3));
        std::uint32_t k0 = std::uint32_t(key), k1 = std::uint32_t(key >> 32);
        for (int round = 0; round < 10; ++round) {
            if (round > 0) k0 += kW0, k1 += kW1;
            __m512i hi0, lo0, hi1, lo1;
            mulhilo16(x0, m0, hi0, lo0);
            mulhilo16(x2, m1, hi1, lo1);
            x0 = _mm512_xor_si512(_mm512_xor_si512(hi1, x1), _mm512_set1_epi32(int(k0)));
            x1 = lo1;
            x2 = _mm512_xor_si512(_mm512_xor_si512(hi0, x3), _mm512_set1_epi32(int(k1)));
            x3 = lo0;
        }
        // Block-major per 128-bit quarter (quarter q of s_j holds block b + 4q + j), then the
        // quarters transposed so that each register holds four consecutive blocks.
        const __m512i t0 = _mm512_unpacklo_epi32(x0, x1), t1 = _mm512_unpacklo_epi32(x2, x3);
        const __m512i t2 = _mm512_unpackhi_epi32(x0, x1), t3 = _mm512_unpackhi_epi32(x2, x3);
        const __m512i s0 = _mm512_unpacklo_epi64(t0, t1), s1 = _mm512_unpackhi_epi64(t0, t1);
        const __m512i s2 = _mm512_unpacklo_epi64(t2, t3), s3 = _mm512_unpackhi_epi64(t2, t3);
        const __m512i u0 = _mm512_shuffle_i64x2(s0, s1, 0x44), u1 = _mm512_shuffle_i64x2(s0, s1, 0xEE);
        const __m512i u2 = _mm512_shuffle_i64x2(s2, s3, 0x44), u3 = _mm512_shuffle_i64x2(s2, s3, 0xEE);
        __m512i* o = reinterpret_cast<__m512i*>(out + 4 * b);
        _mm512_storeu_si512(o + 0, _mm512_shuffle_i64x2(u0, u2, 0x88));
        _mm512_storeu_si512(o + 1, _mm512_shuffle_i64x2(u0, u2, 0xDD));
        _mm512_storeu_si512(o + 2, _mm512_shuffle_i64x2(u1, u3, 0x88));
        _mm512_storeu_si512(o + 3, _mm512_shuffle_i64x2(u1, u3, 0xDD));
    }
    return b;
}
#pragma GCC diagnostic pop

using lane::have_avx2;
using lane::have_avx512;
#endif

}  // namespace

void philox4x32_blocks(std::uint64_t key, std::uint32_t first, std::uint32_t c1,
                       std::uint32_t c2, std::uint32_t c3, std::size_t count, std::uint32_t* out) {
    std::size_t done = 0;
#ifdef SHAPESIM_PHILOX_SIMD
    if (have_avx512()) done = philox_avx512(key, first, c1, c2, c3, count, out);
    if (have_avx2())
        done += philox_avx2(key, first + std::uint32_t(done), c1, c2, c3, count - done, out + 4 * done);
#endif
    philox_scalar(key, first + std::uint32_t(done), c1, c2, c3, count - done, out + 4 * done);
}

namespace {

// The single-precision ziggurat: layer widths × 2⁻²⁴ and rectangle edges as floats, so that
// x = float(top 24 bits) × width is one exact conversion and one rounded multiply, the same
// in every lane width.
struct Ziggurat32 {
    alignas(64) float width[128];  ///< x_layer · 2⁻²⁴
    alignas(64) float inner[128];  ///< x_{layer+1}: below it the word decides alone
    Ziggurat32() {
        const Ziggurat& z = Ziggurat::instance();
        for (int i = 0; i < 128; ++i) {
            width[i] = float(z.edge(i) * 0x1.0p-24);
            inner[i] = float(z.edge(i + 1));
        }
    }
};
const Ziggurat32& ziggurat32() {
    static const Ziggurat32 table;
    return table;
}

// out[i] = the deviate of words[i] where it decides alone; returns how many did not (their
// out[] is left to the caller), listing them in `slow`.
long ziggurat_scalar(const std::uint32_t* words, long begin, long n, float* out, long* slow) {
    const Ziggurat32& t = ziggurat32();
    long count = 0;
    for (long i = begin; i < n; ++i) {
        const std::uint32_t w = words[i];
        const int layer = int(w & 127);
        const float x = float(w >> 8) * t.width[layer];
        out[i] = (w & 128) ? -x : x;
        if (!(x < t.inner[layer])) slow[count++] = i;
    }
    return count;
}

#ifdef SHAPESIM_PHILOX_SIMD
__attribute__((target("avx2"))) long ziggurat_avx2(const std::uint32_t* words, long begin, long n,
                                                   float* out, long* slow, long* done) {
    const Ziggurat32& t = ziggurat32();
    const __m256i low7 = _mm256_set1_epi32(127), bit7 = _mm256_set1_epi32(128);
    long count = 0, i = begin;
    for (; i + 8 <= n; i += 8) {
        const __m256i w = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(words + i));
        const __m256i layer = _mm256_and_si256(w, low7);
        const __m256 u = _mm256_cvtepi32_ps(_mm256_srli_epi32(w, 8));
        const __m256 x = _mm256_mul_ps(u, _mm256_i32gather_ps(t.width, layer, 4));
        const __m256 inner = _mm256_i32gather_ps(t.inner, layer, 4);
        const __m256 sign = _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_and_si256(w, bit7), 24));
        _mm256_storeu_ps(out + i, _mm256_xor_ps(x, sign));
        unsigned rejected = ~unsigned(_mm256_movemask_ps(_mm256_cmp_ps(x, inner, _CMP_LT_OQ))) & 0xFFu;
        while (rejected) {
            slow[count++] = i + __builtin_ctz(rejected);
            rejected &= rejected - 1;
        }
    }
    *done = i;
    return count;
}

// Sixteen words at a time, the tables' 128 entries looked up from registers (four two-table
// permutes and a choice by the layer's top two bits) instead of gathered from memory.
#pragma GCC diagnostic push
#ifndef __clang__
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif  // GCC bug 105593, as above
// table[layer] for a 128-entry table in eight registers.
__attribute__((target("avx512f"))) inline __m512 lookup128(const __m512* table, __m512i layer) {
    const __m512 t01 = _mm512_permutex2var_ps(table[0], layer, table[1]);
    const __m512 t23 = _mm512_permutex2var_ps(table[2], layer, table[3]);
    const __m512 t45 = _mm512_permutex2var_ps(table[4], layer, table[5]);
    const __m512 t67 = _mm512_permutex2var_ps(table[6], layer, table[7]);
    const __mmask16 bit5 = _mm512_test_epi32_mask(layer, _mm512_set1_epi32(32));
    const __mmask16 bit6 = _mm512_test_epi32_mask(layer, _mm512_set1_epi32(64));
    return _mm512_mask_blend_ps(bit6, _mm512_mask_blend_ps(bit5, t01, t23),
                                _mm512_mask_blend_ps(bit5, t45, t67));
}

__attribute__((target("avx512f"))) long ziggurat_avx512(const std::uint32_t* words, long begin,
                                                       long n, float* out, long* slow, long* done) {
    const Ziggurat32& t = ziggurat32();
    __m512 width[8], inner[8];
    for (int q = 0; q < 8; ++q) {
        width[q] = _mm512_load_ps(t.width + 16 * q);
        inner[q] = _mm512_load_ps(t.inner + 16 * q);
    }
    const __m512i low7 = _mm512_set1_epi32(127), bit7 = _mm512_set1_epi32(128);
    long count = 0, i = begin;
    for (; i + 16 <= n; i += 16) {
        const __m512i w = _mm512_loadu_si512(words + i);
        const __m512i layer = _mm512_and_si512(w, low7);
        const __m512 u = _mm512_cvtepi32_ps(_mm512_srli_epi32(w, 8));
        const __m512 x = _mm512_mul_ps(u, lookup128(width, layer));
        const __m512i sign = _mm512_slli_epi32(_mm512_and_si512(w, bit7), 24);
        _mm512_storeu_ps(out + i, _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(x), sign)));
        unsigned rejected = unsigned(_mm512_cmp_ps_mask(x, lookup128(inner, layer), _CMP_NLT_UQ));
        while (rejected) {
            slow[count++] = i + __builtin_ctz(rejected);
            rejected &= rejected - 1;
        }
    }
    *done = i;
    return count;
}
#pragma GCC diagnostic pop
#endif

// Defined below, after the lanes' helpers.
long settle_slow(const std::uint32_t* words, long* slow, std::array<std::uint64_t, 4>* blocks,
                 long n, float* out);

}  // namespace

void WhiteNoise::row(long row, long first, long count, float* out) const {
    if (count <= 0) return;
    require(row >= -margin && first >= -margin &&
                row + margin < (1L << 32) && first + count + margin <= (1L << 32),
            "white noise: pixel outside the keyed range");
    constexpr std::uint64_t purpose = fnv1a_64("white noise");
    const std::uint64_t q0 = std::uint64_t(first + margin), q1 = q0 + std::uint64_t(count);
    const std::uint64_t b0 = q0 / 4, b1 = (q1 + 3) / 4;
    words_.resize(4 * (b1 - b0));
    slow_.resize(std::size_t(count));
    philox4x32_blocks(seed_, std::uint32_t(b0), std::uint32_t(row + margin), std::uint32_t(purpose),
                      std::uint32_t(purpose >> 32), b1 - b0, words_.data());
    const std::uint32_t* w = words_.data() + (q0 - 4 * b0);
    long done = 0, slow = 0;
#ifdef SHAPESIM_PHILOX_SIMD
    if (have_avx512()) slow = ziggurat_avx512(w, 0, count, out, slow_.data(), &done);
    if (have_avx2()) slow += ziggurat_avx2(w, done, count, out, slow_.data() + slow, &done);
#endif
    slow += ziggurat_scalar(w, done, count, out, slow_.data() + slow);
    // The words that did not decide alone: the wedge or tail test, from the pixel's own stream.
    // The streams' first blocks are computed together; most words are settled by a block's
    // first two words (settle_slow, in lanes), the rest one at a time by Ziggurat::finish.
    static constexpr PurposeHash retry("white noise retry");
    const std::uint64_t row_key = (std::uint64_t(row + margin) << 32) + q0;
    ids_.resize(std::size_t(slow));
    blocks_.resize(std::size_t(slow));
    for (long k = 0; k < slow; ++k) ids_[std::size_t(k)] = row_key + std::uint64_t(slow_[std::size_t(k)]);
    RandomStream::first_blocks(seed_, ids_.data(), ids_.size(), retry, blocks_.data());
    const long unsettled = settle_slow(w, slow_.data(), blocks_.data(), slow, out);
    const Ziggurat& zig = Ziggurat::instance();
    for (long k = 0; k < unsettled; ++k) {
        const long i = slow_[std::size_t(k)];
        RandomStream more(seed_, row_key + std::uint64_t(i), retry, blocks_[std::size_t(k)]);
        const float x = std::abs(out[i]);
        const double z = zig.finish(int(w[i] & 127), double(x), more);
        out[i] = float((w[i] & 128) ? -z : z);
    }
}

namespace {

using lane::Doubles4;
using lane::Mask4;
using lane::Words4;

SHAPESIM_LANES bool any(Mask4 m) {
    const Mask4 halves = m | __builtin_shufflevector(m, m, 2, 3, 0, 1);
    return (halves[0] | halves[1]) != 0;
}

SHAPESIM_LANES Mask4 real_lanes(int lanes) { return Mask4{0, 1, 2, 3} < lanes; }

// The top 53 bits of each word as a double, exactly (AVX2 has no 64-bit integer conversion):
// the top 32 and the next 21 bits each become a double by the 2⁵² trick, and their sum is exact.
SHAPESIM_LANES Doubles4 top53(Words4 w) {
    constexpr std::uint64_t two52 = 0x4330000000000000ULL;
    const Doubles4 high = lane::from_bits((w >> 32) | two52) - 0x1.0p52;
    const Doubles4 low = lane::from_bits(((w >> 11) & 0x1fffffULL) | two52) - 0x1.0p52;
    return high * 0x1.0p21 + low;
}

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
__attribute__((always_inline)) inline void photon_run(const std::uint32_t* words, long n, double gain,
                                                     double* pixels, long offset,
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
#ifdef SHAPESIM_PHILOX_SIMD
__attribute__((target("avx2"))) void photon_run_avx2(const std::uint32_t* words, long n, double gain,
                                                     double* pixels, long offset,
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

#ifdef SHAPESIM_PHILOX_SIMD
// Bit k set where pixel k of the four at `s` is bright (NaN is not).
__attribute__((target("avx2"))) inline unsigned bright_bits(const double* s, __m256d least) {
    const __m256d v = _mm256_loadu_pd(s);
    return unsigned(_mm256_movemask_pd(_mm256_and_pd(_mm256_cmp_pd(v, _mm256_setzero_pd(), _CMP_GT_OQ),
                                                     _mm256_cmp_pd(v, least, _CMP_GE_OQ))));
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
#ifdef SHAPESIM_PHILOX_SIMD
    if (have_avx2()) return next_bright_avx2(pixels, from, count, least, bright);
#endif
    return next_bright_scalar(pixels, from, count, least, bright);
}

// Ziggurat::slow's first steps for the words that did not decide alone (slow[0 … n): pixel
// indices into words and out; blocks: each one's first "white noise retry" block), four at a
// time in lanes: the wedge test with word 0 and, when it fails, the fresh word 1 (settled if
// that lands in its rectangle); in the base layer, the tail's first trial with words 0 and 1.
// The same operations on the same numbers as Ziggurat::slow, whose ln and e^x are lane_math's:
// the same bits. Settled pixels get their deviate; the others are moved to the front of slow
// and blocks, in order, and counted.
__attribute__((always_inline)) inline long settle_slow_lanes(const std::uint32_t* words, long* slow,
                                                             std::array<std::uint64_t, 4>* blocks,
                                                             long n, float* out) {
    const Ziggurat& zig = Ziggurat::instance();
    constexpr double r = Ziggurat::tail_start;
    long unsettled = 0;
    for (long k = 0; k < n; k += 4) {
        const int lanes = int(std::min(4L, n - k));
        // Lanes made from scalars (past the end, copies of the last), not written one by one:
        // a vector read after lane-by-lane writes waits for them.
        const long s[4] = {k, k + std::min(1, lanes - 1), k + std::min(2, lanes - 1),
                           k + std::min(3, lanes - 1)};
        const auto layer = [&](int j) { return int(words[slow[s[j]]] & 127); };
        const auto fresh = [&](int j) { return int(blocks[s[j]][1] & 127); };
        const auto x_of = [&](int j) { return double(std::abs(out[slow[s[j]]])); };
        const Doubles4 x = {x_of(0), x_of(1), x_of(2), x_of(3)};
        const Doubles4 f_layer = {zig.density(layer(0)), zig.density(layer(1)),
                                  zig.density(layer(2)), zig.density(layer(3))};
        const Doubles4 f_next = {zig.density(layer(0) + 1), zig.density(layer(1) + 1),
                                 zig.density(layer(2) + 1), zig.density(layer(3) + 1)};
        const Doubles4 width = {zig.edge(fresh(0)), zig.edge(fresh(1)), zig.edge(fresh(2)),
                                zig.edge(fresh(3))};
        const Doubles4 inner = {zig.edge(fresh(0) + 1), zig.edge(fresh(1) + 1),
                                zig.edge(fresh(2) + 1), zig.edge(fresh(3) + 1)};
        const Words4 b0 = {blocks[s[0]][0], blocks[s[1]][0], blocks[s[2]][0], blocks[s[3]][0]};
        const Words4 b1 = {blocks[s[0]][1], blocks[s[1]][1], blocks[s[2]][1], blocks[s[3]][1]};
        const Mask4 base = Words4{std::uint64_t(layer(0)), std::uint64_t(layer(1)),
                                  std::uint64_t(layer(2)), std::uint64_t(layer(3))} == 0;
        const Doubles4 top0 = top53(b0), top1 = top53(b1);
        // The wedge: accepted under the curve, else the fresh word's abscissa.
        const Doubles4 u = top0 * 0x1.0p-53;  // uniform()
        const Mask4 under = f_layer + u * (f_next - f_layer) < lane::exp(-0.5 * x * x);
        const Doubles4 fresh_x = top1 * 0x1.0p-53 * width;
        const Mask4 fresh_inside = fresh_x < inner;
        // The tail: t = −ln(u₁)/R, accepted when −2 ln u₂ > t².
        const Doubles4 t = -lane::log((top0 + 0.5) * 0x1.0p-53) / r;  // uniform_open()
        const Doubles4 y = -lane::log((top1 + 0.5) * 0x1.0p-53);
        const Mask4 tail_ok = 2.0 * y > t * t;
        const Mask4 settled = base ? tail_ok : (under | fresh_inside);
        const Doubles4 z = base ? r + t : (under ? x : fresh_x);
        for (int j = 0; j < lanes; ++j) {
            const long s = k + j, i = slow[s];
            if (settled[j]) {
                out[i] = float((words[i] & 128) ? -z[j] : z[j]);
            } else {
                slow[unsettled] = i;
                blocks[unsettled] = blocks[s];
                ++unsettled;
            }
        }
    }
    return unsettled;
}

#ifdef SHAPESIM_PHILOX_SIMD
__attribute__((target("avx2"))) long settle_slow_avx2(const std::uint32_t* words, long* slow,
                                                      std::array<std::uint64_t, 4>* blocks, long n,
                                                      float* out) {
    return settle_slow_lanes(words, slow, blocks, n, out);
}
#endif

long settle_slow(const std::uint32_t* words, long* slow, std::array<std::uint64_t, 4>* blocks,
                 long n, float* out) {
#ifdef SHAPESIM_PHILOX_SIMD
    if (have_avx2()) return settle_slow_avx2(words, slow, blocks, n, out);
#endif
    return settle_slow_lanes(words, slow, blocks, n, out);
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
                          std::uint32_t(purpose), std::uint32_t(purpose >> 32), std::size_t(i1 - i0),
                          words_.data());
#ifdef SHAPESIM_PHILOX_SIMD
        if (have_avx2())
            photon_run_avx2(words_.data(), i1 - i0, gain, pixels + i0, i0, open_pixels_, open_means_);
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
#ifdef SHAPESIM_PHILOX_SIMD
    if (have_avx2())
        settle_open_avx2(open_pixels_.data(), open_means_.data(), blocks_.data(), keys_.data(),
                         long(open), gain, pixels, seed_);
    else
#endif
        settle_open_baseline(open_pixels_.data(), open_means_.data(), blocks_.data(),
                             keys_.data(), long(open), gain, pixels, seed_);
}

namespace {

using Floats8 = float __attribute__((vector_size(32)));

struct TapRows {
    const float* const* a;  ///< per tap, the row holding w(p + d) for pixel 0
    const float* const* b;  ///< per paired tap, w(p − d); null for single taps
    const float* weight;
    std::size_t count;
};

// out[i] = Σ_t weight_t (a_t[i] + b_t[i]) (or weight_t a_t[i]), taps in order, for pixels
// from `i` on, four lane groups of V at a time (`i` is left at the first pixel of an unfinished
// four, for sum_taps_one and sum_taps_tail). Four independent sums keep the adder busy (one sum's taps wait on each other),
// and each pixel is still its own sum in tap order, the same bits in any width.
template <class V>
__attribute__((always_inline)) inline void sum_taps_lanes(const TapRows& taps, long nx, float* out, long& i) {
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
__attribute__((always_inline)) inline void sum_taps_one(const TapRows& taps, long nx, float* out, long& i) {
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

#ifdef SHAPESIM_PHILOX_SIMD
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
                if (here != 0.0 || there != 0.0) taps_.push_back({float(0.5 * (here + there)), dx, dy, true});
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
    return ring_.data() + std::size_t(((row % width) + width) % width) * std::size_t(nx_ + 2 * radius_);
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
#ifdef SHAPESIM_PHILOX_SIMD
    if (have_avx512()) {
        sum_taps_avx512(rows, nx_, out_.data());
        return out_.data();
    }
#endif
    sum_taps(rows, nx_, out_.data());
    return out_.data();
}

}  // namespace shapesim
