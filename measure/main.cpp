// shapesim-measure: placeholder until the program is implemented (its issue is open).
// --help states the purpose (DESIGN §1) and --version works; anything else exits 2.
#include "shapesim/app/run_main.hpp"

namespace {
const char* const description =
    "Measure morphology diagnostics of an image (shapesim.morph/1) and compare real\n"
    "with simulated catalogues.\n"
    "\n"
    "Planned use (DESIGN.md §1; not available yet):\n"
    "  shapesim-measure sim.fits > sim.morph.jsonl";
}  // namespace

int main(int argc, char** argv) {
    return shapesim::app::run_placeholder(argc, argv, "shapesim-measure", description);
}
