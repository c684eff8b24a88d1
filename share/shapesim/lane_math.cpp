#include "shapesim/lane_math.hpp"

#include <cstdlib>
#include <string>

namespace shapesim::lane {

namespace {

enum class Simd { none, avx2, avx512 };

Simd simd() {
#ifdef SHAPESIM_LANES_X86
    static const Simd level = [] {
        const char* asked = std::getenv("SHAPESIM_SIMD");
        const std::string want = asked ? asked : "";
        if (want == "none") return Simd::none;
        __builtin_cpu_init();
        if (want != "avx2" && __builtin_cpu_supports("avx512f")) return Simd::avx512;
        return __builtin_cpu_supports("avx2") ? Simd::avx2 : Simd::none;
    }();
    return level;
#else
    return Simd::none;
#endif
}

}  // namespace

bool have_avx2() { return simd() != Simd::none; }
bool have_avx512() { return simd() == Simd::avx512; }

}  // namespace shapesim::lane
