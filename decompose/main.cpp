// shapesim-decompose: placeholder until the program is implemented (its issue is open).
// --help states the purpose (DESIGN §1) and --version works; anything else exits 2.
#include "shapesim/app/run_main.hpp"

namespace {
const char* const description =
    "Fit each postage stamp with a polar shapelet series, optimising the centre, the\n"
    "scale beta and n_max. Writes shapesim.shapelet/1 records (galaxies and the PSF).\n"
    "\n"
    "Planned use (DESIGN.md §1; not available yet):\n"
    "  shapesim-decompose --stamps stamps.fits < sources.jsonl > shapelets.jsonl";
}  // namespace

int main(int argc, char** argv) {
    return shapesim::app::run_placeholder(argc, argv, "shapesim-decompose", description);
}
