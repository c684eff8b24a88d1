// montage: data | model | residual panels of decomposed objects as one greyscale PGM image,
// like the paper's Fig. 1. Reads the `--models` file of shapesim-decompose.
//
//   montage MODELS.fits ID[,ID…] OUT.pgm [ZOOM]
//
// One row per object; the three panels of a row share one asinh stretch set by the data
// (sky at 10% grey, the data's peak at white), so a residual that looks like the sky's noise
// is one the model has taken up completely. Convert with e.g. `convert OUT.pgm OUT.png`.
#include "shapesim/app/atomic_file.hpp"
#include "shapesim/app/run_main.hpp"
#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

using namespace shapesim;

namespace {

std::vector<std::string> split(const std::string& list) {
    std::vector<std::string> out;
    std::stringstream s(list);
    std::string id;
    while (std::getline(s, id, ','))
        if (!id.empty()) out.push_back(id);
    return out;
}

int run(int argc, const char* const argv[]) {
    if (argc < 4 || argc > 5) {
        std::cerr << "usage: montage MODELS.fits ID[,ID...] OUT.pgm [ZOOM]\n";
        return 2;
    }
    const std::vector<std::string> ids = split(argv[2]);
    const int zoom = argc == 5 ? std::max(1, std::atoi(argv[4])) : 4;
    FitsReader fits(argv[1]);
    struct Row {
        ImageArray panel[3];
    };
    std::vector<Row> rows;
    int width = 0, height = 0;
    for (const std::string& id : ids) {
        Row row;
        const char* suffix[3] = {".data", ".model", ".residual"};
        for (int k = 0; k < 3; ++k) {
            fits.move_to(id + suffix[k]);
            row.panel[k] = fits.read_image();
        }
        width = std::max(width, int(row.panel[0].cols()));
        height = std::max(height, int(row.panel[0].rows()));
        rows.push_back(std::move(row));
    }
    const int gap = 2;
    const int nx = (3 * width + 2 * gap) * zoom, ny = int(rows.size()) * (height + gap) * zoom;
    std::vector<unsigned char> pixels(std::size_t(nx) * std::size_t(ny), 0);
    for (std::size_t r = 0; r < rows.size(); ++r) {
        const ImageArray& data = rows[r].panel[0];
        // Noise from the data's median absolute deviation; stretch asinh(I/σ).
        std::vector<double> values(data.data(), data.data() + data.size());
        std::nth_element(values.begin(), values.begin() + std::ptrdiff_t(values.size() / 2),
                         values.end());
        const double median = values[values.size() / 2];
        for (double& v : values) v = std::abs(v - median);
        std::nth_element(values.begin(), values.begin() + std::ptrdiff_t(values.size() / 2),
                         values.end());
        const double sigma = std::max(1.4826 * values[values.size() / 2], 1e-30);
        const double top = std::asinh(std::max(data.maxCoeff() / sigma, 1.0));
        const double bottom = -0.1 / 0.9 * top;  // sky (0) at 10% grey
        for (int k = 0; k < 3; ++k) {
            const ImageArray& p = rows[r].panel[k];
            for (Eigen::Index j = 0; j < p.rows(); ++j)
                for (Eigen::Index i = 0; i < p.cols(); ++i) {
                    const double v = std::isfinite(p(j, i)) ? std::asinh(p(j, i) / sigma) : bottom;
                    const double t = std::clamp((v - bottom) / (top - bottom), 0.0, 1.0);
                    const auto grey = static_cast<unsigned char>(std::lround(255.0 * t));
                    // FITS rows run upward; image rows downward.
                    const int x0 = (k * (width + gap) + int(i)) * zoom;
                    const int y0 = (int(r) * (height + gap) + (height - 1 - int(j))) * zoom;
                    for (int b = 0; b < zoom; ++b)
                        for (int a = 0; a < zoom; ++a)
                            pixels[std::size_t(y0 + b) * std::size_t(nx) + std::size_t(x0 + a)] =
                                grey;
                }
        }
    }
    app::AtomicTextFile out(argv[3]);
    out.stream() << "P5\n" << nx << " " << ny << "\n255\n";
    out.stream().write(reinterpret_cast<const char*>(pixels.data()),
                       std::streamsize(pixels.size()));
    out.commit();
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "montage", run); }
