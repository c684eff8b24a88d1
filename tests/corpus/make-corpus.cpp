// Writes the bad- and odd-input corpus of tests/corpus/ (issue 15): `make corpus` runs it into
// tests/corpus/cases/, and the files are committed, so the matrix test never depends on this
// program's build. Every image is the same small field (galaxies, a star, Gaussian noise of
// σ = 1, pixel scale 0.04″) written the many ways real data arrive: each BITPIX with
// BSCALE/BZERO, tile-compressed, in an extension, without or with an unusual WCS, degenerate
// shapes and values. cfitsio directly (not the library under test), and our own generator
// (splitmix64 + Box–Muller), so the bytes do not depend on the C++ library's distributions.
#include "tool_support.hpp"

#include <fitsio.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <limits>
#include <string>
#include <vector>

namespace {

constexpr int kSize = 128;

using Pixels = std::vector<double>;  // row-major, (x, y) at [y * nx + x], 0-based

void check(int status, const std::string& what) {
    if (status == 0) return;
    char text[FLEN_STATUS];
    fits_get_errstatus(status, text);
    std::fprintf(stderr, "make-corpus: %s: %s\n", what.c_str(), text);
    std::exit(1);
}

// An elliptical exponential galaxy (or a Gaussian star) of total flux `flux`, added in place.
void add_profile(Pixels& p, int nx, int ny, double x0, double y0, double flux, double r,
                 double q, double angle, bool gaussian) {
    const double c = std::cos(angle), s = std::sin(angle);
    Pixels shape(p.size());
    double sum = 0;
    for (int y = 0; y < ny; ++y)
        for (int x = 0; x < nx; ++x) {
            const double dx = x - x0, dy = y - y0;
            const double u = c * dx + s * dy, v = (-s * dx + c * dy) / q;
            const double rr = std::sqrt(u * u + v * v) / r;
            shape[y * nx + x] = gaussian ? std::exp(-0.5 * rr * rr) : std::exp(-rr);
            sum += shape[y * nx + x];
        }
    for (std::size_t k = 0; k < p.size(); ++k) p[k] += flux * shape[k] / sum;
}

// The field: five galaxies of S/N 30–400 and one star on noise of σ = 1.
Pixels field(int nx, int ny, std::uint64_t seed) {
    Pixels p(static_cast<std::size_t>(nx) * ny, 0.0);
    shapesim::testing::SplitMix rng{seed};
    for (double& v : p) v = rng.normal();
    const double fx = nx / 128.0, fy = ny / 128.0;
    add_profile(p, nx, ny, 40 * fx, 44 * fy, 4000, 4.0, 0.5, 0.6, false);
    add_profile(p, nx, ny, 90 * fx, 30 * fy, 1500, 2.5, 0.8, -0.3, false);
    add_profile(p, nx, ny, 70 * fx, 90 * fy, 2500, 3.0, 0.35, 1.4, false);
    add_profile(p, nx, ny, 20 * fx, 100 * fy, 600, 1.8, 0.7, 0.0, false);
    add_profile(p, nx, ny, 105 * fx, 70 * fy, 900, 2.0, 0.6, 2.2, false);
    add_profile(p, nx, ny, 100 * fx, 108 * fy, 3000, 1.2, 1.0, 0.0, true);  // the star
    return p;
}

struct Header {
    bool wcs = true;                                   // north-up TAN WCS, 0.04″ pixels
    std::function<void(fitsfile*, int&)> extra = {};  // more keywords
};

// Write `p` (nx × ny) as BITPIX `bitpix` into a new file; integer types are scaled so that
// [lo, hi] spans the type's range with BSCALE/BZERO. `compress`: Rice tile compression.
void write_image(const std::string& path, const Pixels& p, int nx, int ny, int bitpix,
                 const Header& header = {}, bool in_extension = false, bool compress = false) {
    std::remove(path.c_str());
    fitsfile* f = nullptr;
    int status = 0;
    fits_create_file(&f, path.c_str(), &status);
    check(status, path);
    if (in_extension) fits_create_img(f, BYTE_IMG, 0, nullptr, &status);
    if (compress) {  // quantised floats, as fpack writes them; a fixed dither seed
        fits_set_compression_type(f, RICE_1, &status);
        fits_set_dither_seed(f, 1, &status);
    }
    long naxes[2] = {nx, ny};
    fits_create_img(f, bitpix, 2, naxes, &status);
    if (in_extension) fits_write_key(f, TSTRING, "EXTNAME", (void*)"SCI", nullptr, &status);
    if (bitpix > 0) {
        double lo = std::numeric_limits<double>::infinity(), hi = -lo;
        for (double v : p)
            if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
        const double levels = bitpix == 8 ? 255.0 : bitpix == 16 ? 65535.0 : 4294967295.0;
        const double type_min = bitpix == 8 ? 0.0 : -(levels + 1) / 2;
        double bscale = (hi - lo) / levels, bzero = lo - type_min * bscale;
        fits_write_key(f, TDOUBLE, "BSCALE", &bscale, nullptr, &status);
        fits_write_key(f, TDOUBLE, "BZERO", &bzero, nullptr, &status);
        fits_set_bscale(f, bscale, bzero, &status);
    }
    double gain = 1000, zp = 25;
    fits_write_key(f, TDOUBLE, "GAIN", &gain, "e-/unit (corpus)", &status);
    fits_write_key(f, TDOUBLE, "MAGZERO", &zp, "AB mag of one unit (corpus)", &status);
    if (header.wcs) shapesim::testing::write_tan_wcs_cards(f, nx, ny, 0.04, 189.2, 62.2, status);
    if (header.extra) header.extra(f, status);
    std::vector<double> data(p);
    fits_write_img(f, TDOUBLE, 1, static_cast<LONGLONG>(data.size()), data.data(), &status);
    fits_close_file(f, &status);
    check(status, path);
}

void write_text(const std::string& path, const std::string& text) {
    std::ofstream(path, std::ios::binary) << text;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: make-corpus DIR\n");
        return 2;
    }
    const std::string dir = std::string(argv[1]) + "/";
    const int n = kSize;
    const Pixels good = field(n, n, 1);
    const auto out = [&](const char* name) { return dir + name; };

    // Formats.
    write_image(out("good.fits"), good, n, n, FLOAT_IMG);
    write_image(out("bitpix8.fits"), good, n, n, BYTE_IMG);
    write_image(out("bitpix16.fits"), good, n, n, SHORT_IMG);
    write_image(out("bitpix32.fits"), good, n, n, LONG_IMG);
    write_image(out("bitpix-64.fits"), good, n, n, DOUBLE_IMG);
    write_image(out("fpack.fits"), good, n, n, FLOAT_IMG, {}, false, true);
    write_image(out("extension.fits"), good, n, n, FLOAT_IMG, {}, true);

    // Headers.
    write_image(out("no-wcs.fits"), good, n, n, FLOAT_IMG, {false});
    write_image(out("blank-ctype.fits"), good, n, n, FLOAT_IMG,
                {false, [](fitsfile* f, int& status) {
                     double one = 1;
                     fits_write_key(f, TSTRING, "CTYPE1", (void*)"", nullptr, &status);
                     fits_write_key(f, TSTRING, "CTYPE2", (void*)"", nullptr, &status);
                     fits_write_key(f, TDOUBLE, "CDELT1", &one, nullptr, &status);
                     fits_write_key(f, TDOUBLE, "CDELT2", &one, nullptr, &status);
                 }});
    write_image(out("sip.fits"), good, n, n, FLOAT_IMG,
                {true, [](fitsfile* f, int& status) {
                     // TAN with SIP distortion of up to 0.05 pixel at the corners.
                     int order = 2;
                     double a02 = 2e-5, a20 = -1.5e-5, b11 = 1e-5;
                     fits_update_key(f, TSTRING, "CTYPE1", (void*)"RA---TAN-SIP", nullptr,
                                     &status);
                     fits_update_key(f, TSTRING, "CTYPE2", (void*)"DEC--TAN-SIP", nullptr,
                                     &status);
                     fits_write_key(f, TINT, "A_ORDER", &order, nullptr, &status);
                     fits_write_key(f, TDOUBLE, "A_0_2", &a02, nullptr, &status);
                     fits_write_key(f, TDOUBLE, "A_2_0", &a20, nullptr, &status);
                     fits_write_key(f, TINT, "B_ORDER", &order, nullptr, &status);
                     fits_write_key(f, TDOUBLE, "B_1_1", &b11, nullptr, &status);
                 }});

    // Shapes.
    write_image(out("row.fits"), field(200, 1, 2), 200, 1, FLOAT_IMG);
    write_image(out("column.fits"), field(1, 200, 3), 1, 200, FLOAT_IMG);
    write_image(out("tiny.fits"), field(3, 3, 4), 3, 3, FLOAT_IMG);

    // Values.
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double inf = std::numeric_limits<double>::infinity();
    write_image(out("all-zero.fits"), Pixels(n * n, 0.0), n, n, FLOAT_IMG);
    write_image(out("all-nan.fits"), Pixels(n * n, nan), n, n, FLOAT_IMG);
    Pixels p = good;
    for (int k = 0; k < 40; ++k) p[(k * 2654435761u) % p.size()] = k % 2 ? inf : -inf;
    write_image(out("inf.fits"), p, n, n, FLOAT_IMG);
    p = good;
    for (int k = 0; k < 40; ++k) p[(k * 2654435761u) % p.size()] = k % 2 ? 1e38 : -1e38;
    write_image(out("huge.fits"), p, n, n, FLOAT_IMG);
    p = good;
    for (double& v : p) v *= 1e-30;  // a field in erg/s/cm²/Å-like units
    write_image(out("tiny-values.fits"), p, n, n, FLOAT_IMG);
    p = good;
    for (int k = 0; k < 400; ++k) p[(k * 2654435761u) % p.size()] = nan;  // blank pixels
    write_image(out("some-nan.fits"), p, n, n, FLOAT_IMG);
    p = good;
    for (int k = 1; k <= 30; ++k) p[(k * 2246822519u) % p.size()] += 300 + 20 * k;  // cosmics
    write_image(out("hot-pixels.fits"), p, n, n, FLOAT_IMG);
    p = good;
    // A star 200× brighter than the field's, flat at the full well (5000) and bleeding
    // along its column, as a saturated CCD star looks.
    add_profile(p, n, n, 64, 64, 600000, 1.2, 1.0, 0.0, true);
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            double& v = p[y * n + x];
            if (v > 5000 || (x >= 63 && x <= 65 && std::abs(y - 64) < 30)) v = 5000;
        }
    write_image(out("saturated-star.fits"), p, n, n, FLOAT_IMG);
    // The field inside a zero-filled frame, tilted 30° as a rotated mosaic's footprint is:
    // zeros, not NaN, with no weight map to say so.
    {
        const int m = 2 * n;
        Pixels framed(std::size_t(m) * m, 0.0);
        const double c = std::cos(M_PI / 6), s = std::sin(M_PI / 6);
        for (int y = 0; y < m; ++y)
            for (int x = 0; x < m; ++x) {
                const double u = c * (x - m / 2.0) + s * (y - m / 2.0) + n / 2.0;
                const double v = -s * (x - m / 2.0) + c * (y - m / 2.0) + n / 2.0;
                const int i = int(std::floor(u)), j = int(std::floor(v));
                if (i >= 0 && j >= 0 && i < n && j < n)
                    framed[std::size_t(y) * m + x] = good[j * n + i];
            }
        write_image(out("zero-border.fits"), framed, m, m, FLOAT_IMG);
    }

    // Weight maps (inverse variance; the field's noise is σ = 1).
    write_image(out("weight.fits"), Pixels(n * n, 1.0), n, n, FLOAT_IMG);
    p.assign(n * n, 1.0);
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < 20; ++x) p[y * n + x] = 0;  // an unexposed strip
    write_image(out("weight-zeros.fits"), p, n, n, FLOAT_IMG);
    p.assign(n * n, 1.0);
    for (int k = 0; k < 300; ++k) p[(k * 2654435761u) % p.size()] = nan;
    write_image(out("weight-nan.fits"), p, n, n, FLOAT_IMG);
    write_image(out("weight-all-zero.fits"), Pixels(n * n, 0.0), n, n, FLOAT_IMG);
    write_image(out("weight-small.fits"), Pixels(64 * 64, 1.0), 64, 64, FLOAT_IMG);

    // Broken files.
    {
        std::ifstream in(out("good.fits"), std::ios::binary);
        std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        write_text(out("truncated.fits"), bytes.substr(0, bytes.size() / 2));
        write_text(out("header-only.fits"), bytes.substr(0, 2880));
    }
    write_text(out("empty.fits"), "");
    write_text(out("text.fits"), "SIMPLE = T, but this is a text file\n");
    {
        fitsfile* f = nullptr;
        int status = 0;
        const std::string path = out("naxis0.fits");
        std::remove(path.c_str());
        fits_create_file(&f, path.c_str(), &status);
        fits_create_img(f, FLOAT_IMG, 0, nullptr, &status);
        fits_close_file(f, &status);
        check(status, path);
    }
    {
        fitsfile* f = nullptr;
        int status = 0;
        const std::string path = out("cube.fits");
        std::remove(path.c_str());
        long naxes[3] = {32, 32, 3};
        std::vector<float> zeros(32 * 32 * 3, 0.5f);
        fits_create_file(&f, path.c_str(), &status);
        fits_create_img(f, FLOAT_IMG, 3, naxes, &status);
        fits_write_img(f, TFLOAT, 1, static_cast<LONGLONG>(zeros.size()), zeros.data(), &status);
        fits_close_file(f, &status);
        check(status, path);
    }

    // JSON inputs any record reader may meet (the matrix derives the schema-aware ones).
    write_text(out("empty.jsonl"), "");
    write_text(out("blank-lines.jsonl"), "\n\n  \n");
    write_text(out("not-json.jsonl"), "id x y flux\n1 10 20 300\n");
    write_text(out("array.jsonl"), "[1, 2, 3]\n");
    write_text(out("nan-literal.jsonl"), "{\"schema\": \"shapesim.source/1\", \"x\": NaN}\n");
    write_text(out("deep.jsonl"), std::string(100000, '[') + std::string(100000, ']') + "\n");
    std::string binary;
    for (int k = 0; k < 1024; ++k) binary += static_cast<char>((k * 37) & 0xff);
    write_text(out("binary.jsonl"), binary);
    return 0;
}
