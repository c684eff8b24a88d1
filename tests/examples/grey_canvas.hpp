// A greyscale picture for the example programs' figures (montage, perturbations, panels):
// images pasted through an asinh stretch, written as a binary PGM (convert with pnmtopng).
#pragma once

#include "shapesim/atomic_file.hpp"
#include "shapesim/error.hpp"
#include "shapesim/image.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace shapesim::examples {

/// Noise of an image from its median absolute deviation (finite pixels), ≥ 1e-30.
inline double mad_sigma(const ImageArray& image) {
    std::vector<double> v;
    for (Eigen::Index k = 0; k < image.size(); ++k)
        if (std::isfinite(image.data()[k])) v.push_back(image.data()[k]);
    require(!v.empty(), "an image has no finite pixel");
    const auto mid = v.begin() + std::ptrdiff_t(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    const double median = *mid;
    for (double& x : v) x = std::abs(x - median);
    std::nth_element(v.begin(), mid, v.end());
    return std::max(1.4826 * *mid, 1e-30);
}

/// grey = 255 · clamp((asinh(I/scale) − bottom)/(top − bottom)); non-finite pixels at bottom.
struct AsinhStretch {
    double scale = 1.0, bottom = 0.0, top = 1.0;
    unsigned char operator()(double value) const {
        const double v = std::isfinite(value) ? std::asinh(value / scale) : bottom;
        const double t = std::clamp((v - bottom) / (top - bottom), 0.0, 1.0);
        return static_cast<unsigned char>(std::lround(255.0 * t));
    }
};

class GreyCanvas {
public:
    GreyCanvas(int nx, int ny) : nx_(nx), ny_(ny), pixels_(std::size_t(nx) * std::size_t(ny), 0) {}
    /// `image` with its top row (the last FITS row: FITS rows run upward) at canvas row
    /// `top`, first column at `left`, each pixel a zoom × zoom block.
    void paste(const ImageArray& image, int left, int top, int zoom, const AsinhStretch& stretch) {
        for (Eigen::Index j = 0; j < image.rows(); ++j)
            for (Eigen::Index i = 0; i < image.cols(); ++i) {
                const unsigned char grey = stretch(image(j, i));
                const int x0 = left + int(i) * zoom, y0 = top + int(image.rows() - 1 - j) * zoom;
                for (int b = 0; b < zoom; ++b)
                    for (int a = 0; a < zoom; ++a)
                        pixels_[std::size_t(y0 + b) * std::size_t(nx_) + std::size_t(x0 + a)] = grey;
            }
    }
    /// Write the binary PGM atomically.
    void write(const std::string& path) const {
        AtomicTextFile out(path);
        out.stream() << "P5\n" << nx_ << " " << ny_ << "\n255\n";
        out.stream().write(reinterpret_cast<const char*>(pixels_.data()),
                           std::streamsize(pixels_.size()));
        out.commit();
    }

private:
    int nx_, ny_;
    std::vector<unsigned char> pixels_;
};

}  // namespace shapesim::examples
