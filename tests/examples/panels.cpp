// panels: FITS images side by side as one greyscale PGM, at one scale and one stretch — real
// and simulated fields compared by eye (the paper's Figs. 2 and 4).
//
//   panels OUT.pgm IMAGE [IMAGE…]
//
// Every panel uses the first image's stretch: asinh(I/σ) with σ from the first image's median
// absolute deviation, the sky at 10% grey and 1000σ at white. Panels of different sizes are
// top-aligned. The first image HDU of each file is read (cfitsio syntax allowed).
#include "shapesim/app/atomic_file.hpp"
#include "shapesim/app/run_main.hpp"
#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <vector>

using namespace shapesim;

namespace {

double mad_sigma(const ImageArray& image) {
    std::vector<double> v;
    v.reserve(std::size_t(image.size()));
    for (Eigen::Index k = 0; k < image.size(); ++k)
        if (std::isfinite(image.data()[k])) v.push_back(image.data()[k]);
    require(!v.empty(), "the first image has no finite pixel");
    const auto mid = v.begin() + std::ptrdiff_t(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    const double median = *mid;
    for (double& x : v) x = std::abs(x - median);
    std::nth_element(v.begin(), mid, v.end());
    return std::max(1.4826 * *mid, 1e-30);
}

int run(int argc, const char* const argv[]) {
    if (argc < 3) {
        std::cerr << "usage: panels OUT.pgm IMAGE [IMAGE...]\n";
        return 2;
    }
    std::vector<ImageArray> images;
    for (int k = 2; k < argc; ++k) {
        FitsReader fits(argv[k], FitsStart::first_image);
        images.push_back(fits.read_image());
    }
    const double sigma = mad_sigma(images[0]);
    const double top = std::asinh(1000.0), bottom = -0.1 / 0.9 * top;
    const int gap = 4;
    int nx = -gap, ny = 0;
    for (const auto& im : images) {
        nx += int(im.cols()) + gap;
        ny = std::max(ny, int(im.rows()));
    }
    std::vector<unsigned char> pixels(std::size_t(nx) * std::size_t(ny), 0);
    int x0 = 0;
    for (const auto& im : images) {
        for (Eigen::Index j = 0; j < im.rows(); ++j)
            for (Eigen::Index i = 0; i < im.cols(); ++i) {
                const double v = std::isfinite(im(j, i)) ? std::asinh(im(j, i) / sigma) : bottom;
                const double t = std::clamp((v - bottom) / (top - bottom), 0.0, 1.0);
                // FITS rows run upward; image rows downward.
                const std::size_t row = std::size_t(im.rows() - 1 - j);
                pixels[row * std::size_t(nx) + std::size_t(x0 + int(i))] =
                    static_cast<unsigned char>(std::lround(255.0 * t));
            }
        x0 += int(im.cols()) + gap;
    }
    app::AtomicTextFile out(argv[1]);
    out.stream() << "P5\n" << nx << " " << ny << "\n255\n";
    out.stream().write(reinterpret_cast<const char*>(pixels.data()), std::streamsize(pixels.size()));
    out.commit();
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "panels", run); }
