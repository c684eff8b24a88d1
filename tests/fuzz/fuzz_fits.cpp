// libFuzzer harness: the FITS header and image path (issue 15). The input is written to a
// file and opened as every program opens an image: the first image HDU, its HDU list, its
// pixels, its WCS (or a --pixel-scale geometry without one), as a stamp file, and as a
// RealGalaxyCatalog table (its columns read; the files it names are not opened). A
// shapesim::Error is a clean refusal; anything else is a bug. cfitsio is a system library
// without sanitizer instrumentation: only crashes inside it show.
#include "refused_or_read.hpp"
#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/geometry.hpp"
#include "shapesim/real_galaxy_catalog.hpp"

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>
#include <unistd.h>

using namespace shapesim;
using shapesim::fuzz::refused_or_read;

namespace {

const std::string& scratch_file() {
    static const std::string path =
        "/tmp/shapesim-fuzz-" + std::to_string(static_cast<long>(getpid())) + ".fits";
    return path;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string& path = scratch_file();
    {
        std::ofstream out(path, std::ios::binary | std::ios::trunc);
        out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    }
    refused_or_read([&] {
        FitsReader fits(path, FitsStart::first_image);
        refused_or_read([&] { fits.list_hdus(); });
        refused_or_read([&] { fits.read_image(); });
        refused_or_read([&] {
            if (has_wcs(fits)) read_wcs(fits);
        });
    });
    refused_or_read([&] { read_field_geometry(path, 0.04, 10.0, 20.0); });
    refused_or_read([&] {
        FitsReader fits(path);
        read_stamp(fits, "1");
    });
    refused_or_read([&] { read_real_galaxy_catalog(path); });
    return 0;
}
