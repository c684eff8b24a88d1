// A noise's pixel-to-pixel correlation: what shapesim-detect measures on a real sky
// (noise.hpp), what a simulation's noise is drawn to have, and what a fit's degrees of
// freedom depend on (lsq.hpp noise_take_up).
#pragma once

#include <cstdlib>
#include <vector>

namespace shapesim {

/// A normalised 2-D autocorrelation ξ(dx, dy) = ⟨n(p) n(p + d)⟩ / ⟨n²⟩, |dx|, |dy| ≤ radius
/// (ξ(0, 0) = 1; 0 beyond the radius).
struct NoiseCorrelation {
    int radius = 0;
    std::vector<double> values;  ///< (2·radius + 1)², row-major: index (dy + r)(2r + 1) + dx + r
    double at(int dx, int dy) const {
        if (std::abs(dx) > radius || std::abs(dy) > radius) return 0.0;
        return values[std::size_t((dy + radius) * (2 * radius + 1) + dx + radius)];
    }
};

}  // namespace shapesim
