// The nearest model whose light is nowhere negative (a truncated, noisy fit rings below zero;
// a renderer that clips the negative half keeps the positive half as a visible ring): nearest
// in ∫(f − f')² among the models of the same β and n_max whose pixel-integrated image at
// β = 3 pixels is ≥ 0, by Dykstra's alternating projections (Boyle & Dykstra 1986) between the
// models' span and the non-negative images.
// Derivation: docs/algorithms.md#positive-models
#pragma once

#include "shapesim/model.hpp"

namespace shapesim {

/// What nearest_non_negative() did (light below zero as pixel_holes() counts it at β = 3).
struct PositiveModel {
    ShapeletModel model;           ///< the nearest non-negative model (β, n_max, centre kept)
    double negative_before = 0.0;  ///< the input's light below zero over its flux
    double negative_after = 0.0;   ///< the result's, where the iterations stopped
    double change = 0.0;           ///< ‖f' − f‖/‖f‖
    int iterations = 0;
};

/// The model nearest to `model` whose drawn light below zero is at most `tolerance` of its
/// flux (the file comment); `model` itself when it already is, or when its flux is not positive.
/// Stops after `max_iterations` with what it reached.
PositiveModel nearest_non_negative(const ShapeletModel& model, double tolerance = 1e-3,
                                   int max_iterations = 3000);

}  // namespace shapesim
