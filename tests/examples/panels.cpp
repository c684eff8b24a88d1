// panels: FITS images side by side as one greyscale PGM, at one scale and one stretch — real
// and simulated fields compared by eye (the paper's Figs. 2 and 4).
//
//   panels OUT.pgm IMAGE [IMAGE…]
//
// Every panel uses the first image's stretch: asinh(I/σ) with σ from the first image's median
// absolute deviation, the sky at 10% grey and 1000σ at white. Panels of different sizes are
// top-aligned. The first image HDU of each file is read (cfitsio syntax allowed).
#include "app/run_main.hpp"
#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "grey_canvas.hpp"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <vector>

using namespace shapesim;

namespace {

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
    const double sigma = examples::mad_sigma(images[0]);
    const double top = std::asinh(1000.0), bottom = -0.1 / 0.9 * top;
    const int gap = 4;
    int nx = -gap, ny = 0;
    for (const auto& im : images) {
        nx += int(im.cols()) + gap;
        ny = std::max(ny, int(im.rows()));
    }
    examples::GreyCanvas canvas(nx, ny);
    const examples::AsinhStretch stretch{sigma, bottom, top};
    int left = 0;
    for (const auto& im : images) {
        canvas.paste(im, left, 0, 1, stretch);  // top-aligned
        left += int(im.cols()) + gap;
    }
    canvas.write(argv[1]);
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "panels", run); }
