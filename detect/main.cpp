// shapesim-detect: placeholder until the program is implemented (its issue is open).
// --help states the purpose (DESIGN §1) and --version works; anything else exits 2.
#include "shapesim/app/run_main.hpp"

namespace {
const char* const description =
    "Find the objects of a deep image: background, detection, segmentation, star\n"
    "rejection and postage stamps. Writes a shapesim.source/1 catalogue.\n"
    "\n"
    "Planned use (DESIGN.md §1; not available yet):\n"
    "  shapesim-detect hdf.fits --weight hdf_wht.fits --stamps stamps.fits > sources.jsonl";
}  // namespace

int main(int argc, char** argv) {
    return shapesim::app::run_placeholder(argc, argv, "shapesim-detect", description);
}
