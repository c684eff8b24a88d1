// The shapesim version (`git describe --always --dirty` at build time), for --version and the
// VERSION keyword of FITS outputs. Only version.o carries it, so a new commit relinks but does
// not recompile the library.
#pragma once

namespace shapesim {

/// e.g. "620eb1e" or "620eb1e-dirty"; "unknown" outside a git checkout.
const char* version();

}  // namespace shapesim
