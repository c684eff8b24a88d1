// Shear calibration: a shape catalogue matched to the truth it was simulated from, and the
// linear response e = (1 + m) g + c fitted per component by ordinary least squares (Heymans
// et al. 2006, STEP1; Massey et al. 2007, STEP2): m the multiplicative bias, c the additive.
// Errors by block bootstrap (a ring of rotated copies is one block); matching to the nearest
// true galaxy within a radius, at most one object per galaxy.
// Derivation: docs/algorithms.md#shear-calibration
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace shapesim {

/// For each of `measured` (x, y), the index of the nearest of `truth` (x, y) within `radius`
/// (same units), or −1; each truth index appears at most once (the nearer measurement keeps
/// it; ties to the lower index). Error unless radius > 0 and every position is finite.
std::vector<long> match_nearest(const std::vector<double>& truth_x,
                                const std::vector<double>& truth_y,
                                const std::vector<double>& measured_x,
                                const std::vector<double>& measured_y, double radius);

/// One matched galaxy: its true reduced shear, its measured shear estimate, its block.
struct ShearPoint {
    double g1 = 0.0, g2 = 0.0;  ///< true reduced shear
    double e1 = 0.0, e2 = 0.0;  ///< the catalogue's estimate (divided by any responsivity)
    std::uint64_t block = 0;     ///< bootstrap unit (a ring, else the galaxy)
};

/// e = (1 + m) g + c for one component.
struct ComponentFit {
    double m = 0.0, c = 0.0;
    double m_err = 0.0, c_err = 0.0;  ///< bootstrap standard deviations (0 without resamples)
};

struct ShearCalibration {
    long galaxies = 0, blocks = 0;
    ComponentFit one, two;
};

/// The fit of `points` with `resamples` bootstrap resamples of blocks drawn from `seed`.
/// Error when fewer than 3 points, or a component's g does not vary.
ShearCalibration fit_shear_calibration(const std::vector<ShearPoint>& points, int resamples,
                                       std::uint64_t seed);

/// `points` split into `bins` groups of (nearly) equal size by `value` (NaN values left out),
/// each fitted: the bin's value range and its fit (a bin too small or with one shear: no fit).
struct CalibrationBin {
    double lo = 0.0, hi = 0.0;
    std::optional<ShearCalibration> fit;
    long galaxies = 0;
};
std::vector<CalibrationBin> fit_in_bins(const std::vector<ShearPoint>& points,
                                        const std::vector<double>& value, int bins,
                                        int resamples, std::uint64_t seed);

}  // namespace shapesim
