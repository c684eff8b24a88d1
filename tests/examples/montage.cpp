// montage: data | model | residual panels of decomposed objects as one greyscale PGM image,
// like the paper's Fig. 1. Reads the `--models` file of shapesim-decompose.
//
//   montage MODELS.fits ID[,ID…] OUT.pgm [ZOOM]
//
// One row per object; the three panels of a row share one asinh stretch set by the data
// (sky at 10% grey, the data's peak at white), so a residual that looks like the sky's noise
// is one the model has taken up completely. Convert with e.g. `convert OUT.pgm OUT.png`.
#include "app/run_main.hpp"
#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "grey_canvas.hpp"

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
    examples::GreyCanvas canvas(nx, ny);
    for (std::size_t r = 0; r < rows.size(); ++r) {
        // One asinh(I/σ) stretch per row, σ from the data's MAD: sky (0) at 10% grey, the
        // data's peak at white.
        const ImageArray& data = rows[r].panel[0];
        const double sigma = examples::mad_sigma(data);
        const double top = std::asinh(std::max(data.maxCoeff() / sigma, 1.0));
        const examples::AsinhStretch stretch{sigma, -0.1 / 0.9 * top, top};
        for (int k = 0; k < 3; ++k) {
            const ImageArray& p = rows[r].panel[k];
            // Panels bottom-aligned in their row.
            canvas.paste(p, k * (width + gap) * zoom,
                         (int(r) * (height + gap) + height - int(p.rows())) * zoom, zoom, stretch);
        }
    }
    canvas.write(argv[3]);
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "montage", run); }
