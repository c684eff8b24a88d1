// The harnesses' one rule: a shapesim::Error is a clean refusal of the input; any other
// exception escapes to libFuzzer, which reports it as a crash.
#pragma once

#include "shapesim/error.hpp"

namespace shapesim::fuzz {

template <class F>
void refused_or_read(F&& f) {
    try {
        f();
    } catch (const Error&) {
    }
}

}  // namespace shapesim::fuzz
