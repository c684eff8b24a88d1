#include "shapesim/pixel_noise.hpp"

#include "shapesim/error.hpp"
#include "shapesim/rng.hpp"

#include <Random123/philox.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>

#if defined(__x86_64__)
#include <immintrin.h>
#define SHAPESIM_PHILOX_SIMD 1
#endif

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

// AVX2 when the CPU has it, unless SHAPESIM_SIMD=none asks for the scalar code (the program
// test comparing the two: the same bits either way).
bool have_avx2() {
    static const bool yes = [] {
        const char* asked = std::getenv("SHAPESIM_SIMD");
        if (asked && std::string(asked) == "none") return false;
        __builtin_cpu_init();
        return __builtin_cpu_supports("avx2") != 0;
    }();
    return yes;
}
#endif

}  // namespace

void philox4x32_blocks(std::uint64_t key, std::uint32_t first, std::uint32_t c1,
                       std::uint32_t c2, std::uint32_t c3, std::size_t count, std::uint32_t* out) {
    std::size_t done = 0;
#ifdef SHAPESIM_PHILOX_SIMD
    if (have_avx2()) done = philox_avx2(key, first, c1, c2, c3, count, out);
#endif
    philox_scalar(key, first + std::uint32_t(done), c1, c2, c3, count - done, out + 4 * done);
}

namespace {

// The single-precision ziggurat: layer widths × 2⁻²⁴ and rectangle edges as floats, so that
// x = float(top 24 bits) × width is one exact conversion and one rounded multiply, the same
// in every lane width.
struct Ziggurat32 {
    alignas(32) float width[128];  ///< x_layer · 2⁻²⁴
    alignas(32) float inner[128];  ///< x_{layer+1}: below it the word decides alone
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
__attribute__((target("avx2"))) long ziggurat_avx2(const std::uint32_t* words, long n, float* out,
                                                   long* slow, long* done) {
    const Ziggurat32& t = ziggurat32();
    const __m256i low7 = _mm256_set1_epi32(127), bit7 = _mm256_set1_epi32(128);
    long count = 0, i = 0;
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
#endif

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
    if (have_avx2()) slow = ziggurat_avx2(w, count, out, slow_.data(), &done);
#endif
    slow += ziggurat_scalar(w, done, count, out, slow_.data() + slow);
    // The words that did not decide alone: the wedge or tail test, from the pixel's own stream.
    const Ziggurat& zig = Ziggurat::instance();
    for (long k = 0; k < slow; ++k) {
        const long i = slow_[std::size_t(k)];
        static constexpr PurposeHash retry("white noise retry");
        RandomStream more(seed_, (std::uint64_t(row + margin) << 32) + q0 + std::uint64_t(i), retry);
        const float x = std::abs(out[i]);
        const double z = zig.finish(int(w[i] & 127), double(x), more);
        out[i] = float((w[i] & 128) ? -z : z);
    }
}

namespace {

// The uniforms of one pixel's photon draw: its block's two words, then a stream of its own.
class PhotonWords {
public:
    PhotonWords(const std::uint32_t* block, std::uint64_t seed, std::uint64_t pixel)
        : block_(block), seed_(seed), pixel_(pixel) {}
    double uniform() { return double(next() >> 11) * 0x1.0p-53; }
    double uniform_open() { return (double(next() >> 11) + 0.5) * 0x1.0p-53; }

private:
    std::uint64_t next() {
        if (used_ < 2) {
            const std::uint64_t word = block_[2 * used_] | (std::uint64_t(block_[2 * used_ + 1]) << 32);
            ++used_;
            return word;
        }
        static constexpr PurposeHash more("photon noise more");
        if (!more_) more_.emplace(seed_, pixel_, more);
        return more_->next_u64();
    }
    const std::uint32_t* block_;
    std::uint64_t seed_, pixel_;
    int used_ = 0;
    std::optional<RandomStream> more_;
};

}  // namespace

void PhotonNoise::row(long row, long first, long count, double gain, double least,
                      double* pixels) const {
    require(row >= 0 && first >= 0 && row + WhiteNoise::margin < (1L << 32) &&
                first + count + WhiteNoise::margin <= (1L << 32),
            "photon noise: pixel outside the keyed range");
    auto bright = [&](long i) { return pixels[i] > 0.0 && pixels[i] >= least; };
    constexpr std::uint64_t purpose = fnv1a_64("photon noise");
    const std::uint64_t row_key = std::uint64_t(row + WhiteNoise::margin) << 32;
    // Runs of pixels bright enough, each run's blocks drawn together.
    for (long i0 = 0; i0 < count;) {
        if (!bright(i0)) {
            ++i0;
            continue;
        }
        long i1 = i0 + 1;
        while (i1 < count && bright(i1)) ++i1;
        const std::uint64_t q0 = std::uint64_t(first + i0 + WhiteNoise::margin);
        words_.resize(4 * std::size_t(i1 - i0));
        philox4x32_blocks(seed_, std::uint32_t(q0), std::uint32_t(row + WhiteNoise::margin),
                          std::uint32_t(purpose), std::uint32_t(purpose >> 32), std::size_t(i1 - i0),
                          words_.data());
        for (long i = i0; i < i1; ++i) {
            PhotonWords source(words_.data() + 4 * (i - i0), seed_, row_key + q0 + std::uint64_t(i - i0));
            pixels[i] = double(poisson_deviate(pixels[i] * gain, source)) / gain;
        }
        i0 = i1;
    }
}

namespace {

using Floats8 = float __attribute__((vector_size(32)));

struct TapRows {
    const float* const* a;  ///< per tap, the row holding w(p + d) for pixel 0
    const float* const* b;  ///< per paired tap, w(p − d); null for single taps
    const float* weight;
    std::size_t count;
};

// out[i] = Σ_t weight_t (a_t[i] + b_t[i]) (or weight_t a_t[i]), taps in order, eight pixels a
// lane group; the tail by the same sums one at a time.
__attribute__((target_clones("avx2", "default"))) void sum_taps(const TapRows& taps, long nx,
                                                               float* out) {
    long i = 0;
    for (; i + 8 <= nx; i += 8) {
        Floats8 acc = {0, 0, 0, 0, 0, 0, 0, 0};
        for (std::size_t t = 0; t < taps.count; ++t) {
            Floats8 v;
            std::memcpy(&v, taps.a[t] + i, sizeof v);
            if (taps.b[t]) {
                Floats8 u;
                std::memcpy(&u, taps.b[t] + i, sizeof u);
                v = v + u;
            }
            acc = acc + taps.weight[t] * v;
        }
        std::memcpy(out + i, &acc, sizeof acc);
    }
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
    sum_taps(TapRows{a_.data(), b_.data(), weights_.data(), taps_.size()}, nx_, out_.data());
    return out_.data();
}

}  // namespace shapesim
