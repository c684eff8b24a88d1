#include "shapesim/philox.hpp"

#include "shapesim/lane_math.hpp"

#include <cstring>
#include <utility>

namespace shapesim {

namespace {

// Random123's constants for Philox4x32: the multipliers and the Weyl key increments.
constexpr std::uint32_t kM0 = 0xD2511F53u, kM1 = 0xCD9E8D57u;
constexpr std::uint32_t kW0 = 0x9E3779B9u, kW1 = 0xBB67AE85u;

// A lane width: its words V (lane b holds block b) and the little that differs with it: the
// 32 × 32 → 64-bit multiply of each 64-bit lane's low word (vpmuludq; GCC's vector extensions
// make a full 64 × 64-bit multiply of it, three times the work), and the last step of the
// transpose to block-major order, across 128-bit groups. Their methods carry the width's
// target and are inlined into its caller (which has the same target), not forced: GCC refuses
// to force a target's code into the target-less templates below. They take and give lanes by
// reference: clang refuses, as an ABI change, a lane passed by value from a target-less
// function into one with AVX.
struct OneBlock {
    using V = std::uint32_t;
};

#ifdef SHAPESIM_LANES_X86
// Lanes of `bytes`: as words, and as pairs of words.
template <int bytes>
struct Lanes {
    typedef std::uint32_t V __attribute__((vector_size(bytes)));
    typedef std::uint64_t Pairs __attribute__((vector_size(bytes)));
};

struct Avx2Blocks : Lanes<32> {
    __attribute__((target("avx2"))) static void mul_even(const V& a, std::uint32_t m, V& p) {
        p = V(_mm256_mul_epu32(__m256i(a), _mm256_set1_epi32(int(m))));
    }
    // s_j holds block j in its low 128 bits, block 4 + j in its high ones.
    __attribute__((target("avx2"))) static void store(const V& s0, const V& s1, const V& s2,
                                                      const V& s3, std::uint32_t* out) {
        __m256i* o = reinterpret_cast<__m256i*>(out);
        _mm256_storeu_si256(o + 0, _mm256_permute2x128_si256(__m256i(s0), __m256i(s1), 0x20));
        _mm256_storeu_si256(o + 1, _mm256_permute2x128_si256(__m256i(s2), __m256i(s3), 0x20));
        _mm256_storeu_si256(o + 2, _mm256_permute2x128_si256(__m256i(s0), __m256i(s1), 0x31));
        _mm256_storeu_si256(o + 3, _mm256_permute2x128_si256(__m256i(s2), __m256i(s3), 0x31));
    }
};

// (GCC 12's AVX-512 intrinsics start from _mm512_undefined_*: a false "may be used
// uninitialized", or at -Og, the sanitizers' build, "is used uninitialized": GCC bug 105593.)
#pragma GCC diagnostic push
#ifndef __clang__
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
#endif
struct Avx512Blocks : Lanes<64> {
    __attribute__((target("avx512f"))) static void mul_even(const V& a, std::uint32_t m, V& p) {
        p = V(_mm512_mul_epu32(__m512i(a), _mm512_set1_epi32(int(m))));
    }
    // Group q of s_j holds block 4q + j: the groups transposed so that each register holds
    // four consecutive blocks.
    __attribute__((target("avx512f"))) static void store(const V& s0, const V& s1, const V& s2,
                                                         const V& s3, std::uint32_t* out) {
        const __m512i u0 = _mm512_shuffle_i64x2(__m512i(s0), __m512i(s1), 0x44);
        const __m512i u1 = _mm512_shuffle_i64x2(__m512i(s0), __m512i(s1), 0xEE);
        const __m512i u2 = _mm512_shuffle_i64x2(__m512i(s2), __m512i(s3), 0x44);
        const __m512i u3 = _mm512_shuffle_i64x2(__m512i(s2), __m512i(s3), 0xEE);
        __m512i* o = reinterpret_cast<__m512i*>(out);
        _mm512_storeu_si512(o + 0, _mm512_shuffle_i64x2(u0, u2, 0x88));
        _mm512_storeu_si512(o + 1, _mm512_shuffle_i64x2(u0, u2, 0xDD));
        _mm512_storeu_si512(o + 2, _mm512_shuffle_i64x2(u1, u3, 0x88));
        _mm512_storeu_si512(o + 3, _mm512_shuffle_i64x2(u1, u3, 0xDD));
    }
};
#pragma GCC diagnostic pop
#endif

// Word k of a two-register shuffle of n words (b's numbered from n) that interleaves, within
// each 128-bit group of four words, a's and b's elements of `size` words from the group's low
// (half 0) or high half: SSE's unpacklo/unpackhi_epi32 (size 1) and _epi64 (size 2).
constexpr int unpack_index(int k, int n, int half, int size) {
    const int group = k / 4 * 4, j = k % 4, element = j / size;
    return (element % 2 ? n : 0) + group + size * (half * (2 / size) + element / 2) + j % size;
}
template <int half, int size, class V, std::size_t... K>
SHAPESIM_LANES V unpack(V a, V b, std::index_sequence<K...>) {
    return __builtin_shufflevector(a, b, unpack_index(int(K), int(sizeof...(K)), half, size)...);
}
// Even words of a, odd words of b.
constexpr int odd_from_b(int k, int n) { return k % 2 ? n + k : k; }
template <class V, std::size_t... K>
SHAPESIM_LANES V blend_odd(V a, V b, std::index_sequence<K...>) {
    return __builtin_shufflevector(a, b, odd_from_b(int(K), int(sizeof...(K)))...);
}

// (hi, lo) = m · a, 32 × 32 → 64 bits, in each lane: in vector lanes the even words' products
// and the odd ones' (shifted down), their halves blended back in place.
template <class L>
SHAPESIM_LANES void mulhilo(typename L::V a, std::uint32_t m, typename L::V& hi,
                            typename L::V& lo) {
    using V = typename L::V;
    if constexpr (sizeof(V) == sizeof(std::uint32_t)) {
        const std::uint64_t p = std::uint64_t(a) * m;
        hi = std::uint32_t(p >> 32);
        lo = std::uint32_t(p);
    } else {
        using Pairs = typename L::Pairs;
        constexpr auto words = std::make_index_sequence<sizeof(V) / sizeof(std::uint32_t)>();
        V even, odd;
        L::mul_even(a, m, even);
        L::mul_even(V(Pairs(a) >> 32), m, odd);
        lo = blend_odd(even, V(Pairs(odd) << 32), words);
        hi = blend_odd(V(Pairs(even) >> 32), odd, words);
    }
}

// Lanes are blocks and registers words (x_w: word w of each block): out block-major. In vector
// lanes, block-major first within each 128-bit group, then across groups (L::store).
template <class L>
SHAPESIM_LANES void store_blocks(typename L::V x0, typename L::V x1, typename L::V x2,
                                 typename L::V x3, std::uint32_t* out) {
    using V = typename L::V;
    if constexpr (sizeof(V) == sizeof(std::uint32_t)) {
        const V x[4] = {x0, x1, x2, x3};
        std::memcpy(out, x, sizeof x);
    } else {
        constexpr auto words = std::make_index_sequence<sizeof(V) / sizeof(std::uint32_t)>();
        const V t0 = unpack<0, 1>(x0, x1, words), t1 = unpack<0, 1>(x2, x3, words);
        const V t2 = unpack<1, 1>(x0, x1, words), t3 = unpack<1, 1>(x2, x3, words);
        const V s0 = unpack<0, 2>(t0, t1, words), s1 = unpack<1, 2>(t0, t1, words);
        const V s2 = unpack<0, 2>(t2, t3, words), s3 = unpack<1, 2>(t2, t3, words);
        L::store(s0, s1, s2, s3, out);
    }
}

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
            mulhilo<L>(x0, kM0, hi0, lo0);
            mulhilo<L>(x2, kM1, hi1, lo1);
            x0 = hi1 ^ x1 ^ k0;
            x1 = lo1;
            x2 = hi0 ^ x3 ^ k1;
            x3 = lo0;
        }
        store_blocks<L>(x0, x1, x2, x3, out + 4 * b);
    }
    return b;
}

#ifdef SHAPESIM_LANES_X86
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
#ifdef SHAPESIM_LANES_X86
    if (lane::have_avx512()) done = philox_avx512(key, first, c1, c2, c3, count, out);
    if (lane::have_avx2())
        done +=
            philox_avx2(key, first + std::uint32_t(done), c1, c2, c3, count - done, out + 4 * done);
#endif
    philox_lanes<OneBlock>(key, first + std::uint32_t(done), c1, c2, c3, count - done,
                           out + 4 * done);
}

}  // namespace shapesim
