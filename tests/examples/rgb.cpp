// rgb: colour composites of FITS images side by side as one binary PPM — a real field and
// its simulation seen the same way (issue 17's figure).
//
//   rgb OUT.ppm RED GREEN BLUE [RED GREEN BLUE…]
//
// Each image has its median (the sky) subtracted; each channel is divided by its noise (the
// median absolute deviation of the first triple's image of that channel, used for every
// panel), then Lupton et al. (2004, PASP 116, 133)'s
// asinh composite: with I = (r + g + b)/3, every channel times asinh(I/S)/I, so colours keep
// their ratios while the brightness is stretched; the sky sits at black, S = 3 (noise units)
// and 400σ of I saturate. Panels of different sizes are top-aligned; 4 black columns between.
#include "app/run_main.hpp"
#include "shapesim/atomic_file.hpp"
#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "grey_canvas.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <iostream>
#include <vector>

using namespace shapesim;

namespace {

int run(int argc, const char* const argv[]) {
    if (argc < 5 || (argc - 2) % 3 != 0) {
        std::cerr << "usage: rgb OUT.ppm RED GREEN BLUE [RED GREEN BLUE...]\n";
        return 2;
    }
    std::vector<std::array<ImageArray, 3>> panels;
    for (int k = 2; k < argc; k += 3) {
        std::array<ImageArray, 3> panel;
        for (int c = 0; c < 3; ++c) {
            FitsReader fits(argv[k + c], FitsStart::first_image);
            panel[std::size_t(c)] = fits.read_image();
            ImageArray& image = panel[std::size_t(c)];
            std::vector<double> finite;
            for (Eigen::Index i = 0; i < image.size(); ++i)
                if (std::isfinite(image.data()[i])) finite.push_back(image.data()[i]);
            require(!finite.empty(), std::string(argv[k + c]) + ": no finite pixel");
            const auto mid = finite.begin() + std::ptrdiff_t(finite.size() / 2);
            std::nth_element(finite.begin(), mid, finite.end());
            image -= *mid;
            require(panel[std::size_t(c)].rows() == panel[0].rows() &&
                        panel[std::size_t(c)].cols() == panel[0].cols(),
                    "the three images of a panel differ in size");
        }
        panels.push_back(std::move(panel));
    }
    std::array<double, 3> sigma{};
    for (std::size_t c = 0; c < 3; ++c) sigma[c] = examples::mad_sigma(panels[0][c]);
    constexpr double softening = 3.0, saturation = 400.0;
    const double top = std::asinh(saturation / softening);
    const int gap = 4;
    int nx = -gap, ny = 0;
    for (const auto& p : panels) {
        nx += int(p[0].cols()) + gap;
        ny = std::max(ny, int(p[0].rows()));
    }
    std::vector<unsigned char> pixels(std::size_t(nx) * std::size_t(ny) * 3, 0);
    int left = 0;
    for (const auto& p : panels) {
        for (Eigen::Index j = 0; j < p[0].rows(); ++j)
            for (Eigen::Index i = 0; i < p[0].cols(); ++i) {
                std::array<double, 3> v{};
                for (std::size_t c = 0; c < 3; ++c) {
                    const double x = p[c](j, i) / sigma[c];
                    v[c] = std::isfinite(x) ? std::max(x, 0.0) : 0.0;
                }
                const double intensity = (v[0] + v[1] + v[2]) / 3.0;
                const double f = intensity > 0.0 ? std::asinh(intensity / softening) / (top * intensity) : 0.0;
                const std::size_t row = std::size_t(p[0].rows() - 1 - j);  // FITS rows run upward
                const std::size_t at = (row * std::size_t(nx) + std::size_t(left + int(i))) * 3;
                for (std::size_t c = 0; c < 3; ++c)
                    pixels[at + c] = static_cast<unsigned char>(std::lround(255.0 * std::clamp(v[c] * f, 0.0, 1.0)));
            }
        left += int(p[0].cols()) + gap;
    }
    AtomicTextFile out(argv[1]);
    out.stream() << "P6\n" << nx << " " << ny << "\n255\n";
    out.stream().write(reinterpret_cast<const char*>(pixels.data()), std::streamsize(pixels.size()));
    out.commit();
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "rgb", run); }
