// libFuzzer harness: the FITS header and image path (issue 15). The input is written to a
// file and opened as every program opens an image: the first image HDU, its HDU list, its
// pixels, its WCS (or a --pixel-scale geometry without one), as a stamp file, and as a
// RealGalaxyCatalog table (its columns read; the files it names are not opened), and as a
// PSFEx model (read, not fitted: the fit's cost would starve the readers of runs). A
// shapesim::Error is a clean refusal; anything else is a bug. cfitsio is a system library
// without sanitizer instrumentation: only crashes inside it show.
#include "refused_or_read.hpp"
#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/geometry.hpp"
#include "shapesim/psf_field.hpp"
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

// cfitsio sizes some of its buffers from the header before it checks them (a mangled card can
// make it ask calloc for 10^16 bytes while opening the file). Outside ASan, calloc returns
// NULL, cfitsio reports a memory error and the programs refuse the file with one line; ASan
// would abort instead. Letting ASan's malloc return NULL tests what users run. Our own C++
// allocations are still caught: a failed operator new is reported, and libFuzzer's
// -malloc_limit_mb catches any allocation over 2 GB that succeeds.
extern "C" const char* __asan_default_options() { return "allocator_may_return_null=1"; }

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
    refused_or_read([&] { read_psfex(path); });
    return 0;
}
