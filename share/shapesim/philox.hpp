// Philox4x32-10 blocks many at a time (Salmon, Moraes, Dror & Shaw 2011, "Parallel random
// numbers: as easy as 1, 2, 3", SC'11; the same generator as Random123's r123::Philox4x32):
// the keyed bijection of 128-bit counters that the pixel noise (pixel_noise.hpp) draws from.
// The ten rounds are written once for any number of lanes; sixteen blocks at a time with
// AVX-512, eight with AVX2, else one (lane_math.hpp's dispatch): the same bits in every width.
#pragma once

#include <cstddef>
#include <cstdint>

namespace shapesim {

/// `count` Philox4x32-10 blocks with counters (first + b, c1, c2, c3), b = 0 … count − 1,
/// under `key` (low word first): out[4b + w] = word w of block b.
void philox4x32_blocks(std::uint64_t key, std::uint32_t first, std::uint32_t c1,
                       std::uint32_t c2, std::uint32_t c3, std::size_t count, std::uint32_t* out);

}  // namespace shapesim
