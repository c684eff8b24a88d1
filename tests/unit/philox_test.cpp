// philox.hpp: the Philox4x32-10 blocks, in every lane width, against Random123's.
#include "shapesim/philox.hpp"

#include <Random123/philox.h>
#include <gtest/gtest.h>

#include <cstdint>

using namespace shapesim;

// Random123's known answers (kat_vectors: philox4x32 10) and, for every count 0 … 64 (the
// SIMD widths 8 and 16 and their tails) at keys and counters near the 32-bit wrap, r123::Philox4x32
// (run under SHAPESIM_SIMD unset, =avx2 and =none for every width).
TEST(Philox4x32Blocks, EqualsRandom123) {
    std::uint32_t out[4 * 64];
    philox4x32_blocks(0, 0, 0, 0, 0, 1, out);
    EXPECT_EQ(out[0], 0x6627e8d5u);
    EXPECT_EQ(out[1], 0xe169c58du);
    EXPECT_EQ(out[2], 0xbc57ac4cu);
    EXPECT_EQ(out[3], 0x9b00dbd8u);
    philox4x32_blocks(0x299f31d0a4093822ULL, 0x243f6a88u, 0x85a308d3u, 0x13198a2eu, 0x03707344u, 1, out);
    EXPECT_EQ(out[0], 0xd16cfe09u);
    EXPECT_EQ(out[1], 0x94fdccebu);
    EXPECT_EQ(out[2], 0x5001e420u);
    EXPECT_EQ(out[3], 0x24126ea1u);
    for (const std::uint64_t key : {0x0ULL, 0xffffffffffffffffULL, 0x123456789abcdef0ULL})
        for (const std::uint32_t first : {0u, 7u, 0xfffffff0u})
            for (std::size_t count = 0; count <= 64; ++count) {
                philox4x32_blocks(key, first, 11, 0xdeadbeefu, 3, count, out);
                const r123::Philox4x32::key_type k = {{std::uint32_t(key), std::uint32_t(key >> 32)}};
                for (std::size_t b = 0; b < count; ++b) {
                    const r123::Philox4x32::ctr_type c = {{first + std::uint32_t(b), 11, 0xdeadbeefu, 3}};
                    const auto r = r123::Philox4x32()(c, k);
                    for (int w = 0; w < 4; ++w)
                        ASSERT_EQ(out[4 * b + std::size_t(w)], r.v[w]) << key << " " << first << " " << count;
                }
            }
}
