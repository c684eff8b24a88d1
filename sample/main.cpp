// shapesim-sample: placeholder until the program is implemented (its issue is open).
// --help states the purpose (DESIGN §1) and --version works; anything else exits 2.
#include "shapesim/app/run_main.hpp"

namespace {
const char* const description =
    "Draw new galaxies (and stars) from a PDF model over a sky area by Monte Carlo.\n"
    "Writes a shapesim.object/1 catalogue.\n"
    "\n"
    "Planned use (DESIGN.md §1; not available yet):\n"
    "  shapesim-sample morphology.pdf.json --like hdf.fits --seed 7 > objects.jsonl";
}  // namespace

int main(int argc, char** argv) {
    return shapesim::app::run_placeholder(argc, argv, "shapesim-sample", description);
}
