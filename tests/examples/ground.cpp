// ground: a space image as a ground-based telescope would record it, the "ground-based case"
// of the program tests. Real galaxies, blurred by seeing and binned into big pixels, on a
// bright sky, in ADU with BITPIX 16 BSCALE/BZERO, as a CCD frame comes.
//
//   ground IN.fits OUT.fits PIXEL_SCALE ZERO_POINT SEEING BIN SKY EXPOSURE GAIN [SEED]
//
// PIXEL_SCALE: IN's arcsec per pixel (IN may lack a WCS). ZERO_POINT: AB mag of one IN unit.
// SEEING: FWHM of the Gaussian seeing,
// arcsec. BIN: OUT pixel = BIN × BIN IN pixels, summed (flux is kept). SKY: sky level of OUT,
// in IN's units per OUT pixel. EXPOSURE: seconds, when IN is a rate (e⁻/s): OUT's photon
// noise is that of value · EXPOSURE electrons. GAIN: e⁻ per ADU of OUT. OUT holds
// (value · EXPOSURE + noise) / GAIN ADU, sky not subtracted. Its header: a north-up TAN WCS,
// GAIN, EXPTIME, SATURATE and MAGZPT, the AB zero point of one ADU. IN's own noise is binned
// too, but is far below the sky's. FULL_WELL (ADU): pixels above it read it, as a saturated
// CCD's do, and SATURATE is that level (without: the 16-bit range's top, which nothing reaches).
#include "app/run_main.hpp"
#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "../corpus/tool_support.hpp"

#include <fitsio.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <string>
#include <vector>

using namespace shapesim;

namespace {

// Separable Gaussian blur of σ pixels (kernel to ±4σ, normalised; edges mirror).
ImageArray gaussian_blur(const ImageArray& in, double sigma) {
    const int half = int(std::ceil(4 * sigma));
    std::vector<double> kernel(std::size_t(2 * half + 1));
    double sum = 0;
    for (int k = -half; k <= half; ++k)
        sum += kernel[std::size_t(k + half)] = std::exp(-0.5 * k * k / (sigma * sigma));
    for (double& v : kernel) v /= sum;
    const int ny = int(in.rows()), nx = int(in.cols());
    const auto mirror = [](int i, int n) { return i < 0 ? -i - 1 : i >= n ? 2 * n - i - 1 : i; };
    ImageArray rows(ny, nx), out(ny, nx);
    for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) {
            double v = 0;
            for (int k = -half; k <= half; ++k)
                v += kernel[std::size_t(k + half)] * in(j, mirror(i + k, nx));
            rows(j, i) = v;
        }
    for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) {
            double v = 0;
            for (int k = -half; k <= half; ++k)
                v += kernel[std::size_t(k + half)] * rows(mirror(j + k, ny), i);
            out(j, i) = v;
        }
    return out;
}

void check(int status, const std::string& path) {
    if (status == 0) return;
    char text[FLEN_STATUS];
    fits_get_errstatus(status, text);
    throw Error(text, path);
}

int run(int argc, const char* const argv[]) {
    if (argc < 10 || argc > 12) {
        std::cerr << "usage: ground IN.fits OUT.fits PIXEL_SCALE ZERO_POINT SEEING BIN SKY "
                     "EXPOSURE GAIN [SEED [FULL_WELL]]\n";
        return 2;
    }
    const std::string in_path = argv[1], out_path = argv[2];
    const double scale = std::atof(argv[3]), zero_point = std::atof(argv[4]);
    const double seeing = std::atof(argv[5]);
    const int bin = std::atoi(argv[6]);
    const double sky = std::atof(argv[7]), exposure = std::atof(argv[8]), gain = std::atof(argv[9]);
    shapesim::testing::SplitMix noise{argc >= 11 ? std::strtoull(argv[10], nullptr, 10) : 1};
    // A full well, ADU: pixels above it read it (saturated), and SATURATE says so.
    const double full_well = argc == 12 ? std::atof(argv[11]) : 0.0;
    if (argc == 12 && !(full_well > 0)) throw Error("FULL_WELL must be > 0 ADU");
    if (!(scale > 0 && seeing > 0 && bin >= 1 && sky >= 0 && exposure > 0 && gain > 0))
        throw Error("PIXEL_SCALE, SEEING, EXPOSURE and GAIN must be > 0, BIN >= 1, SKY >= 0");

    FitsReader in(in_path, FitsStart::first_image);
    ImageArray image = in.read_image();
    for (Eigen::Index k = 0; k < image.size(); ++k)
        if (!std::isfinite(image.data()[k])) image.data()[k] = 0.0;
    const ImageArray blurred = gaussian_blur(image, seeing / scale / 2.354820045);
    const int nx = int(image.cols()) / bin, ny = int(image.rows()) / bin;
    std::vector<double> adu(std::size_t(nx) * std::size_t(ny));
    double lowest = 1e300, highest = -1e300;
    for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) {
            const double value = blurred.block(j * bin, i * bin, bin, bin).sum() + sky;
            const double electrons = std::max(value, 0.0) * exposure;
            double a = (value * exposure + std::sqrt(electrons) * noise.normal()) / gain;
            if (full_well > 0) a = std::min(a, full_well);
            adu[std::size_t(j) * std::size_t(nx) + std::size_t(i)] = a;
            lowest = std::min(lowest, a);
            highest = std::max(highest, a);
        }

    // BITPIX 16 spanning the frame's range, as a 16-bit CCD read-out scaled to the data.
    double bscale = (highest - lowest) / 65000.0, bzero = 0.5 * (highest + lowest);
    std::remove(out_path.c_str());
    fitsfile* f = nullptr;
    int status = 0;
    fits_create_file(&f, out_path.c_str(), &status);
    check(status, out_path);
    long naxes[2] = {nx, ny};
    fits_create_img(f, SHORT_IMG, 2, naxes, &status);
    fits_write_key(f, TDOUBLE, "BSCALE", &bscale, nullptr, &status);
    fits_write_key(f, TDOUBLE, "BZERO", &bzero, nullptr, &status);
    fits_set_bscale(f, bscale, bzero, &status);
    // A 16-bit read-out saturates at the top of its range, which the scaled data stay below;
    // a full well, at its level (less half a step of the scaling: the stored value rounds).
    double exptime = exposure, gain_key = gain;
    double saturate = full_well > 0 ? full_well - 0.5 * bscale : bzero + 32767 * bscale;
    fits_write_key(f, TDOUBLE, "EXPTIME", &exptime, "s", &status);
    fits_write_key(f, TDOUBLE, "GAIN", &gain_key, "e-/ADU", &status);
    fits_write_key(f, TDOUBLE, "SATURATE", &saturate, "ADU", &status);
    double magzpt = zero_point - 2.5 * std::log10(gain / exposure);  // 1 ADU = gain/exposure units
    fits_write_key(f, TDOUBLE, "MAGZPT", &magzpt, "AB mag of 1 ADU", &status);
    shapesim::testing::write_tan_wcs_cards(f, nx, ny, scale * bin, 53.16, -27.78, status);
    fits_write_img(f, TDOUBLE, 1, LONGLONG(adu.size()), adu.data(), &status);
    fits_close_file(f, &status);
    check(status, out_path);
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "ground", run); }
