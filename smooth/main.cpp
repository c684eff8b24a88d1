// shapesim-smooth: placeholder until the program is implemented (its issue is open).
// --help states the purpose (DESIGN §1) and --version works; anything else exits 2.
#include "shapesim/app/run_main.hpp"

namespace {
const char* const description =
    "Align the shapelet models (rotate, flip), build their parameter space and its\n"
    "smoothing lengths, and write the smoothed PDF model of galaxy morphology.\n"
    "\n"
    "Planned use (DESIGN.md §1; not available yet):\n"
    "  shapesim-smooth < shapelets.jsonl > morphology.pdf.json";
}  // namespace

int main(int argc, char** argv) {
    return shapesim::app::run_placeholder(argc, argv, "shapesim-smooth", description);
}
