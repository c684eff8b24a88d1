#include "shapesim/philox.hpp"

#include "shapesim/lane_math.hpp"

#include <cstring>

#if defined(__x86_64__)
#include <immintrin.h>
#define SHAPESIM_PHILOX_SIMD 1
#endif

// Lanes pass by value to always-inlined helpers; GCC still warns, at each call built without
// AVX, that AVX code would pass them differently (none is ever out of line: lane_math.hpp).
#pragma GCC diagnostic ignored "-Wpsabi"

namespace shapesim {

namespace {

// Random123's constants for Philox4x32: the multipliers and the Weyl key increments.
constexpr std::uint32_t kM0 = 0xD2511F53u, kM1 = 0xCD9E8D57u;
constexpr std::uint32_t kW0 = 0x9E3779B9u, kW1 = 0xBB67AE85u;

// A lane width: its words V (lane b holds block b), the product (hi, lo) = m · a in each lane,
// and the store of four registers (x_w: word w of each lane's block) in block-major order.
// Only these differ with the width; philox_lanes is the same for all. Their methods carry the
// width's target and are inlined into its caller (which has the same target), not forced:
// GCC refuses to force a target's code into the target-less template.
struct OneBlock {
    using V = std::uint32_t;
    static void mulhilo(V a, std::uint32_t m, V& hi, V& lo) {
        const std::uint64_t p = std::uint64_t(a) * m;
        hi = std::uint32_t(p >> 32);
        lo = std::uint32_t(p);
    }
    static void store(V x0, V x1, V x2, V x3, std::uint32_t* out) {
        const V x[4] = {x0, x1, x2, x3};
        std::memcpy(out, x, sizeof x);
    }
};

#ifdef SHAPESIM_PHILOX_SIMD
// Eight blocks at once. A 64-bit multiply (vpmuludq) takes the even lanes' words, and the
// odd ones shifted down; the products' halves are blended back in place. (GCC's vector
// extensions make a full 64 × 64-bit multiply of it: three times the work.)
struct Avx2Blocks {
    using V = std::uint32_t __attribute__((vector_size(32)));
    __attribute__((target("avx2"))) static void mulhilo(V a, std::uint32_t m, V& hi, V& lo) {
        const __m256i mm = _mm256_set1_epi32(int(m));
        const __m256i even = _mm256_mul_epu32(__m256i(a), mm);
        const __m256i odd = _mm256_mul_epu32(_mm256_srli_epi64(__m256i(a), 32), mm);
        lo = V(_mm256_blend_epi32(even, _mm256_slli_epi64(odd, 32), 0xAA));
        hi = V(_mm256_blend_epi32(_mm256_srli_epi64(even, 32), odd, 0xAA));
    }
    // Transposed per 128-bit half (the low half holds blocks 0 … 3, the high half 4 … 7).
    __attribute__((target("avx2"))) static void store(V x0, V x1, V x2, V x3,
                                                      std::uint32_t* out) {
        const __m256i t0 = _mm256_unpacklo_epi32(__m256i(x0), __m256i(x1));
        const __m256i t1 = _mm256_unpacklo_epi32(__m256i(x2), __m256i(x3));
        const __m256i t2 = _mm256_unpackhi_epi32(__m256i(x0), __m256i(x1));
        const __m256i t3 = _mm256_unpackhi_epi32(__m256i(x2), __m256i(x3));
        const __m256i s0 = _mm256_unpacklo_epi64(t0, t1), s1 = _mm256_unpackhi_epi64(t0, t1);
        const __m256i s2 = _mm256_unpacklo_epi64(t2, t3), s3 = _mm256_unpackhi_epi64(t2, t3);
        __m256i* o = reinterpret_cast<__m256i*>(out);
        _mm256_storeu_si256(o + 0, _mm256_permute2x128_si256(s0, s1, 0x20));
        _mm256_storeu_si256(o + 1, _mm256_permute2x128_si256(s2, s3, 0x20));
        _mm256_storeu_si256(o + 2, _mm256_permute2x128_si256(s0, s1, 0x31));
        _mm256_storeu_si256(o + 3, _mm256_permute2x128_si256(s2, s3, 0x31));
    }
};

// Sixteen blocks at once, as Avx2Blocks does eight. (GCC 12's AVX-512 intrinsics start from
// _mm512_undefined_*: a false "may be used uninitialized", GCC bug 105593.)
#pragma GCC diagnostic push
#ifndef __clang__
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
struct Avx512Blocks {
    using V = std::uint32_t __attribute__((vector_size(64)));
    __attribute__((target("avx512f"))) static void mulhilo(V a, std::uint32_t m, V& hi, V& lo) {
        const __m512i mm = _mm512_set1_epi32(int(m));
        const __m512i even = _mm512_mul_epu32(__m512i(a), mm);
        const __m512i odd = _mm512_mul_epu32(_mm512_srli_epi64(__m512i(a), 32), mm);
        lo = V(_mm512_mask_blend_epi32(0xAAAA, even, _mm512_slli_epi64(odd, 32)));
        hi = V(_mm512_mask_blend_epi32(0xAAAA, _mm512_srli_epi64(even, 32), odd));
    }
    // Block-major per 128-bit quarter (quarter q of s_j holds block 4q + j), then the quarters
    // transposed so that each register holds four consecutive blocks.
    __attribute__((target("avx512f"))) static void store(V x0, V x1, V x2, V x3,
                                                         std::uint32_t* out) {
        const __m512i t0 = _mm512_unpacklo_epi32(__m512i(x0), __m512i(x1));
        const __m512i t1 = _mm512_unpacklo_epi32(__m512i(x2), __m512i(x3));
        const __m512i t2 = _mm512_unpackhi_epi32(__m512i(x0), __m512i(x1));
        const __m512i t3 = _mm512_unpackhi_epi32(__m512i(x2), __m512i(x3));
        const __m512i s0 = _mm512_unpacklo_epi64(t0, t1), s1 = _mm512_unpackhi_epi64(t0, t1);
        const __m512i s2 = _mm512_unpacklo_epi64(t2, t3), s3 = _mm512_unpackhi_epi64(t2, t3);
        const __m512i u0 = _mm512_shuffle_i64x2(s0, s1, 0x44), u1 = _mm512_shuffle_i64x2(s0, s1, 0xEE);
        const __m512i u2 = _mm512_shuffle_i64x2(s2, s3, 0x44), u3 = _mm512_shuffle_i64x2(s2, s3, 0xEE);
        __m512i* o = reinterpret_cast<__m512i*>(out);
        _mm512_storeu_si512(o + 0, _mm512_shuffle_i64x2(u0, u2, 0x88));
        _mm512_storeu_si512(o + 1, _mm512_shuffle_i64x2(u0, u2, 0xDD));
        _mm512_storeu_si512(o + 2, _mm512_shuffle_i64x2(u1, u3, 0x88));
        _mm512_storeu_si512(o + 3, _mm512_shuffle_i64x2(u1, u3, 0xDD));
    }
};
#pragma GCC diagnostic pop
#endif

// Lane numbers 0, 1, … (one block: 0).
template <class V>
SHAPESIM_LANES V lane_numbers() {
    V v{};
    if constexpr (sizeof(V) > sizeof(std::uint32_t))
        for (unsigned i = 0; i < sizeof(V) / sizeof(std::uint32_t); ++i) v[i] = i;
    return v;
}

// The blocks first … first + count − 1 by lanes of width L, as many as fill whole lanes;
// returns how many. Philox4x32-10 as Random123's philox.h computes it: ten rounds of two
// multiplies, the key bumped by the Weyl increments between rounds.
template <class L>
SHAPESIM_LANES std::size_t philox_lanes(std::uint64_t key, std::uint32_t first, std::uint32_t c1,
                                        std::uint32_t c2, std::uint32_t c3, std::size_t count,
                                        std::uint32_t* out) {
    using V = typename L::V;
    constexpr std::size_t width = sizeof(V) / sizeof(std::uint32_t);
    const V lanes = lane_numbers<V>(), y1 = V{} + c1, y2 = V{} + c2, y3 = V{} + c3;
    std::size_t b = 0;
    for (; b + width <= count; b += width) {
        V x0 = lanes + (first + std::uint32_t(b)), x1 = y1, x2 = y2, x3 = y3;
        std::uint32_t k0 = std::uint32_t(key), k1 = std::uint32_t(key >> 32);
#pragma GCC unroll 10
        for (int round = 0; round < 10; ++round) {
            if (round > 0) k0 += kW0, k1 += kW1;
            V hi0, lo0, hi1, lo1;
            L::mulhilo(x0, kM0, hi0, lo0);
            L::mulhilo(x2, kM1, hi1, lo1);
            x0 = hi1 ^ x1 ^ k0;
            x1 = lo1;
            x2 = hi0 ^ x3 ^ k1;
            x3 = lo0;
        }
        L::store(x0, x1, x2, x3, out + 4 * b);
    }
    return b;
}

#ifdef SHAPESIM_PHILOX_SIMD
__attribute__((target("avx512f"))) std::size_t philox_avx512(std::uint64_t key, std::uint32_t first,
                                                            std::uint32_t c1, std::uint32_t c2,
                                                            std::uint32_t c3, std::size_t count,
                                                            std::uint32_t* out) {
    return philox_lanes<Avx512Blocks>(key, first, c1, c2, c3, count, out);
}
__attribute__((target("avx2"))) std::size_t philox_avx2(std::uint64_t key, std::uint32_t first,
                                                       std::uint32_t c1, std::uint32_t c2,
                                                       std::uint32_t c3, std::size_t count,
                                                       std::uint32_t* out) {
    return philox_lanes<Avx2Blocks>(key, first, c1, c2, c3, count, out);
}
#endif

}  // namespace

void philox4x32_blocks(std::uint64_t key, std::uint32_t first, std::uint32_t c1,
                       std::uint32_t c2, std::uint32_t c3, std::size_t count, std::uint32_t* out) {
    std::size_t done = 0;
#ifdef SHAPESIM_PHILOX_SIMD
    if (lane::have_avx512()) done = philox_avx512(key, first, c1, c2, c3, count, out);
    if (lane::have_avx2())
        done += philox_avx2(key, first + std::uint32_t(done), c1, c2, c3, count - done, out + 4 * done);
#endif
    philox_lanes<OneBlock>(key, first + std::uint32_t(done), c1, c2, c3, count - done, out + 4 * done);
}

}  // namespace shapesim
