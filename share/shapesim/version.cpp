#include "shapesim/version.hpp"

#ifndef SHAPESIM_VERSION
#define SHAPESIM_VERSION "unknown"
#endif

namespace shapesim {

const char* version() { return SHAPESIM_VERSION; }

}  // namespace shapesim
