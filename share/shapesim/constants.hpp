// Mathematical constants, once (C++17 has no std::numbers).
#pragma once

namespace shapesim {

inline constexpr double pi = 3.14159265358979323846;
inline constexpr double degree = pi / 180.0;  ///< one degree in radians
inline constexpr double arcsec = degree / 3600.0;  ///< one arcsecond in radians

}  // namespace shapesim
