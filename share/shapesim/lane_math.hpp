// ln x, eˣ and asin x written once for a double and for four doubles in vector lanes (GCC
// vector extensions): the same operations in the same order, so a lane gives the bits the
// scalar gives, whatever the lane width or CPU (photon noise draws four pixels at a time and
// must equal rng.hpp's per-pixel draw). fdlibm's algorithms, < 1 ulp; the build's
// -ffp-contract=off keeps a·b + c from becoming an FMA in one width only.
// Derivation: docs/algorithms.md#vector-lanes
#pragma once

#include <cstdint>
#include <cstring>

// On x86-64 the AVX2 and AVX-512 paths are built, each function carrying its target, and
// chosen at run time (have_avx2, have_avx512); elsewhere only the scalar code.
#if defined(__x86_64__)
#include <immintrin.h>
#define SHAPESIM_LANES_X86 1
#endif

// Four-double vectors are passed in AVX registers by AVX code and in memory by other code: an
// out-of-line copy of a function taking lanes, emitted by one and called by the other, would
// read garbage. So everything taking or returning lanes is always inlined, and GCC's -Wpsabi
// warning about the two conventions is moot (the Makefile turns it off).
#define SHAPESIM_LANES inline __attribute__((always_inline))

namespace shapesim::lane {

/// The widest lanes the CPU has — AVX-512 (F), AVX2 or none — unless the environment's
/// SHAPESIM_SIMD asks for narrower ("avx2", or "none": the scalar code). Code that has lanes
/// dispatches on these; every width gives the same bits (the program tests compare them).
bool have_avx2();
bool have_avx512();

using Doubles4 = double __attribute__((vector_size(32)));
using Words4 = std::uint64_t __attribute__((vector_size(32)));
using Mask4 = std::int64_t __attribute__((vector_size(32)));  ///< a comparison's lanes: 0 or −1

SHAPESIM_LANES std::uint64_t bits(double x) {
    std::uint64_t w;
    std::memcpy(&w, &x, sizeof w);
    return w;
}
SHAPESIM_LANES Words4 bits(Doubles4 x) { return (Words4)x; }  // a vector cast keeps the bits
SHAPESIM_LANES double from_bits(std::uint64_t w) {
    double x;
    std::memcpy(&x, &w, sizeof x);
    return x;
}
SHAPESIM_LANES Doubles4 from_bits(Words4 w) { return (Doubles4)w; }

/// |x|, ⌊x⌋ and √x lane by lane (all exact or correctly rounded: any width gives the same bits).
SHAPESIM_LANES double abs(double x) { return from_bits(bits(x) & 0x7fffffffffffffffULL); }
SHAPESIM_LANES Doubles4 abs(Doubles4 x) { return from_bits(bits(x) & 0x7fffffffffffffffULL); }
SHAPESIM_LANES double floor(double x) { return __builtin_floor(x); }
SHAPESIM_LANES Doubles4 floor(Doubles4 x) {
    return Doubles4{__builtin_floor(x[0]), __builtin_floor(x[1]), __builtin_floor(x[2]),
                    __builtin_floor(x[3])};
}
SHAPESIM_LANES double sqrt(double x) { return __builtin_sqrt(x); }
SHAPESIM_LANES Doubles4 sqrt(Doubles4 x) {
    return Doubles4{__builtin_sqrt(x[0]), __builtin_sqrt(x[1]), __builtin_sqrt(x[2]),
                    __builtin_sqrt(x[3])};
}

/// ln x for a positive, normal, finite x (lanes outside that give garbage, not a trap).
template <class D>
SHAPESIM_LANES D log(D x) {
    constexpr double ln2_hi = 6.93147180369123816490e-01, ln2_lo = 1.90821492927058770002e-10;
    constexpr double lg1 = 6.666666666666735130e-01, lg2 = 3.999999999940941908e-01,
                     lg3 = 2.857142874366239149e-01, lg4 = 2.222219843214978396e-01,
                     lg5 = 1.818357216161805012e-01, lg6 = 1.531383769920937332e-01,
                     lg7 = 1.479819860511658591e-01;
    constexpr std::uint64_t root_half = 0x3fe6a09e667f3bcdULL;  // √½'s bits
    // Shift the exponent so that m lands in [√½, √2): k is the exponent of x·√2.
    const auto shifted = bits(x) + (0x3ff0000000000000ULL - root_half);
    const auto mantissa = (shifted & 0x000fffffffffffffULL) + root_half;
    // k as a double, exactly: 2⁵² + (biased exponent) read as a double, less 2⁵² + 1023.
    const D k = from_bits((shifted >> 52) + 0x4330000000000000ULL) - (0x1.0p52 + 1023.0);
    const D f = from_bits(mantissa) - 1.0;
    const D half_f2 = 0.5 * f * f;
    const D s = f / (2.0 + f);
    const D z = s * s, w = z * z;
    const D t1 = w * (lg2 + w * (lg4 + w * lg6));
    const D t2 = z * (lg1 + w * (lg3 + w * (lg5 + w * lg7)));
    const D r = t2 + t1;
    return s * (half_f2 + r) + k * ln2_lo - half_f2 + f + k * ln2_hi;
}

/// eˣ for x ∈ [−708, 709] (no overflow, underflow or NaN handling).
template <class D>
SHAPESIM_LANES D exp(D x) {
    constexpr double ln2_hi = 6.93147180369123816490e-01, ln2_lo = 1.90821492927058770002e-10;
    constexpr double inv_ln2 = 1.44269504088896338700e+00;
    constexpr double p1 = 1.66666666666666019037e-01, p2 = -2.77777777770155933842e-03,
                     p3 = 6.61375632143793436117e-05, p4 = -1.65339022054652515390e-06,
                     p5 = 4.13813679705723846039e-08;
    constexpr double shifter = 0x1.8p52;  // adding it rounds to an integer, to nearest even
    const D shifted = x * inv_ln2 + shifter;
    const D k = shifted - shifter;
    const D hi = x - k * ln2_hi, lo = k * ln2_lo;
    const D r = hi - lo;
    const D t = r * r;
    const D c = r - t * (p1 + t * (p2 + t * (p3 + t * (p4 + t * p5))));
    const D y = 1.0 - ((lo - (r * c) / (2.0 - c)) - hi);
    // 2^k: k sits in the low bits of `shifted` (two's complement); its exponent field.
    const auto scale = (bits(shifted) - bits(D{} + shifter) + 1023) << 52;
    return y * from_bits(scale);
}

/// The top 53 bits of each word as a double, exactly (a uniform deviate's 53 bits, rng.hpp).
/// AVX2 has no 64-bit integer conversion: the top 32 and the next 21 bits each become a double
/// by the 2⁵² trick, and their sum is exact.
SHAPESIM_LANES double top53(std::uint64_t w) { return double(w >> 11); }
SHAPESIM_LANES Doubles4 top53(Words4 w) {
    constexpr std::uint64_t two52 = 0x4330000000000000ULL;
    const Doubles4 high = from_bits((w >> 32) | two52) - 0x1.0p52;
    const Doubles4 low = from_bits(((w >> 11) & 0x1fffffULL) | two52) - 0x1.0p52;
    return high * 0x1.0p21 + low;
}

/// One of two values by a condition (a bool, or a comparison's lanes).
SHAPESIM_LANES double select(bool m, double a, double b) { return m ? a : b; }
SHAPESIM_LANES Doubles4 select(Mask4 m, Doubles4 a, Doubles4 b) { return m ? a : b; }

/// asin x for x ∈ [−1, 1].
template <class D>
SHAPESIM_LANES D asin(D x) {
    constexpr double pio2_hi = 1.57079632679489655800e+00, pio2_lo = 6.12323399573676603587e-17,
                     pio4_hi = 7.85398163397448278999e-01;
    constexpr double ps0 = 1.66666666666666657415e-01, ps1 = -3.25565818622400915405e-01,
                     ps2 = 2.01212532134862925881e-01, ps3 = -4.00555345006794114027e-02,
                     ps4 = 7.91534994289814532176e-04, ps5 = 3.47933107596021167570e-05;
    constexpr double qs1 = -2.40339491173441421878e+00, qs2 = 2.02094576023350569471e+00,
                     qs3 = -6.88283971605453293030e-01, qs4 = 7.70381505559019352791e-02;
    const D ax = abs(x);
    const auto high = bits(ax) >> 32;  // fdlibm's tests on the high word
    const auto tiny = high < 0x3e400000ULL, small = high < 0x3fe00000ULL,
               steep = high >= 0x3fef3333ULL;  // |x| < 2⁻²⁷, < ½, ≥ 0.975
    const D t = select(small, ax * ax, (1.0 - ax) * 0.5);
    const D p = t * (ps0 + t * (ps1 + t * (ps2 + t * (ps3 + t * (ps4 + t * ps5)))));
    const D q = 1.0 + t * (qs1 + t * (qs2 + t * (qs3 + t * qs4)));
    const D w = p / q;
    const D s = sqrt(t);
    const D s_high = from_bits(bits(s) & 0xffffffff00000000ULL);  // √t's leading half
    const D c = (t - s_high * s_high) / (s + s_high);             // and the rest
    const D near_one = pio2_hi - (2.0 * (s + s * w) - pio2_lo);
    const D middle = pio4_hi - ((2.0 * s * w - (pio2_lo - 2.0 * c)) - (pio4_hi - 2.0 * s_high));
    const D magnitude =
        select(small, select(tiny, ax, ax + ax * w), select(steep, near_one, middle));
    return from_bits(bits(magnitude) | (bits(x) & 0x8000000000000000ULL));
}

}  // namespace shapesim::lane

