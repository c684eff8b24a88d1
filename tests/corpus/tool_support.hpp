// What the test tools that make FITS files without the library under test (make-corpus,
// examples/ground) share: a generator of their noise and a TAN WCS written with cfitsio.
#pragma once

#include <fitsio.h>

#include <cmath>
#include <cstdint>

namespace shapesim::testing {

// splitmix64 and Box–Muller: the same bytes on every platform and C++ library (std::
// distributions are implementation-defined).
struct SplitMix {
    std::uint64_t state;
    double uniform() {  // in (0, 1)
        std::uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
        return (static_cast<double>((z ^ (z >> 31)) >> 11) + 0.5) * 0x1.0p-53;
    }
    double normal() {
        const double radius = std::sqrt(-2 * std::log(uniform()));
        return radius * std::cos(2 * M_PI * uniform());
    }
};

// CTYPE, CRPIX (the image centre), CRVAL (ra, dec) and the CD matrix of `scale_arcsec` pixels,
// east left; cfitsio's status convention (no-op once status is set).
inline void write_tan_wcs_cards(fitsfile* f, int nx, int ny, double scale_arcsec, double ra,
                                double dec, int& status) {
    double crpix1 = (nx + 1) / 2.0, crpix2 = (ny + 1) / 2.0;
    double cd = scale_arcsec / 3600.0, mcd = -cd, zero = 0.0;
    fits_write_key(f, TSTRING, "CTYPE1", (void*)"RA---TAN", nullptr, &status);
    fits_write_key(f, TSTRING, "CTYPE2", (void*)"DEC--TAN", nullptr, &status);
    fits_write_key(f, TDOUBLE, "CRPIX1", &crpix1, nullptr, &status);
    fits_write_key(f, TDOUBLE, "CRPIX2", &crpix2, nullptr, &status);
    fits_write_key(f, TDOUBLE, "CRVAL1", &ra, nullptr, &status);
    fits_write_key(f, TDOUBLE, "CRVAL2", &dec, nullptr, &status);
    fits_write_key(f, TDOUBLE, "CD1_1", &mcd, nullptr, &status);
    fits_write_key(f, TDOUBLE, "CD1_2", &zero, nullptr, &status);
    fits_write_key(f, TDOUBLE, "CD2_1", &zero, nullptr, &status);
    fits_write_key(f, TDOUBLE, "CD2_2", &cd, nullptr, &status);
}

}  // namespace shapesim::testing
