// shapesim-render: placeholder until the program is implemented (its issue is open).
// --help states the purpose (DESIGN §1) and --version works; anything else exits 2.
#include "shapesim/app/run_main.hpp"

namespace {
const char* const description =
    "Paint objects into a FITS image: PSF convolution, pixel integration, noise, and\n"
    "FITS output with a WCS.\n"
    "\n"
    "Planned use (DESIGN.md §1; not available yet):\n"
    "  shapesim-render --psf psf.json --like hdf.fits -o sim.fits < objects.jsonl";
}  // namespace

int main(int argc, char** argv) {
    return shapesim::app::run_placeholder(argc, argv, "shapesim-render", description);
}
