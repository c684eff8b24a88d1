// White noise keyed by the field pixel (pixel_noise.hpp; bit by bit in docs/library.md): the
// single-precision ziggurat of one Philox4x32 word per pixel, in lanes, and its slow words.
#include "shapesim/pixel_noise.hpp"

#include "shapesim/error.hpp"
#include "shapesim/lane_math.hpp"
#include "shapesim/rng.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace shapesim {

namespace {

using lane::Doubles4;
using lane::have_avx2;
using lane::have_avx512;
using lane::Mask4;
using lane::top53;
using lane::Words4;

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

#ifdef SHAPESIM_LANES_X86
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
        unsigned rejected =
            ~unsigned(_mm256_movemask_ps(_mm256_cmp_ps(x, inner, _CMP_LT_OQ))) & 0xFFu;
        while (rejected) {
            slow[count++] = i + __builtin_ctz(rejected);
            rejected &= rejected - 1;
        }
    }
    *done = i;
    return count;
}

// Sixteen words at a time, the tables' 128 entries looked up from registers (four two-table
// permutes and a choice by the layer's top two bits) instead of gathered from memory. (GCC
// 12's AVX-512 intrinsics start from _mm512_undefined_*: a false "may be used uninitialized",
// GCC bug 105593.)
#pragma GCC diagnostic push
#ifndef __clang__
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
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
        _mm512_storeu_ps(out + i,
                         _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(x), sign)));
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

#ifdef SHAPESIM_LANES_X86
__attribute__((target("avx2"))) long settle_slow_avx2(const std::uint32_t* words, long* slow,
                                                      std::array<std::uint64_t, 4>* blocks, long n,
                                                      float* out) {
    return settle_slow_lanes(words, slow, blocks, n, out);
}
#endif

long settle_slow(const std::uint32_t* words, long* slow, std::array<std::uint64_t, 4>* blocks,
                 long n, float* out) {
#ifdef SHAPESIM_LANES_X86
    if (have_avx2()) return settle_slow_avx2(words, slow, blocks, n, out);
#endif
    return settle_slow_lanes(words, slow, blocks, n, out);
}

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
#ifdef SHAPESIM_LANES_X86
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
    for (long k = 0; k < slow; ++k)
        ids_[std::size_t(k)] = row_key + std::uint64_t(slow_[std::size_t(k)]);
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

}  // namespace shapesim
