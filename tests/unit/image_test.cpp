// image.hpp: the pixel convention and large_image's huge-page advice.
#include "shapesim/image.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>

using namespace shapesim;

namespace {
// The smaps block of the mapping holding `address`, or "" if none does.
std::string mapping_of(const void* address) {
    const auto a = reinterpret_cast<std::uintptr_t>(address);
    std::ifstream smaps("/proc/self/smaps");
    std::string line, block;
    bool inside = false;
    while (std::getline(smaps, line)) {
        std::uintptr_t lo = 0, hi = 0;
        char dash = 0;
        std::istringstream head(line);
        if (head >> std::hex >> lo >> dash >> hi && dash == '-') {  // a mapping's first line
            if (inside) return block;
            inside = lo <= a && a < hi;
            block.clear();
        }
        if (inside) block += line + "\n";
    }
    return inside ? block : "";
}

std::string thp_mode() {
    std::ifstream in("/sys/kernel/mm/transparent_hugepage/enabled");
    std::string mode;
    std::getline(in, mode);
    return mode;
}
}  // namespace

TEST(Image, FitsCoordinatesOfIndices) {
    EXPECT_EQ(fits_x_of_column(0), 1.0);
    EXPECT_EQ(fits_y_of_row(4095), 4096.0);
}

TEST(Image, LargeImageIsAnOrdinaryImageOnHugePages) {
    ImageArray image = large_image(1000, 1200);  // 9.2 MiB: four whole 2 MiB pages inside
    ASSERT_EQ(image.rows(), 1000);
    ASSERT_EQ(image.cols(), 1200);
    image.setConstant(1.5);
    image(999, 1199) = 2.0;
    EXPECT_EQ(image.sum(), 1.5 * 1000 * 1200 + 0.5);
    const ImageArray small = large_image(3, 4);  // below 4 MiB: no advice, still an image
    EXPECT_EQ(small.size(), 12);

    const std::string mode = thp_mode();
    if (mode.find("[never]") != std::string::npos || mode.empty())
        GTEST_SKIP() << "transparent huge pages are off on this machine: " << mode;
    // The advised middle of the array is a mapping of its own, eligible for huge pages.
    const double* middle = image.data() + image.size() / 2;
    const std::string block = mapping_of(middle);
    ASSERT_FALSE(block.empty());
    const std::size_t eligible = block.find("THPeligible:");
    ASSERT_NE(eligible, std::string::npos) << block;
    EXPECT_EQ(block[block.find_first_not_of(' ', eligible + 12)], '1') << block;
    EXPECT_NE(block.find(" hg"), std::string::npos) << block;  // VmFlags: hg = MADV_HUGEPAGE
}
