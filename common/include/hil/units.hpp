// Units: SI inside the code; degrees, MPa, mm², litres at the edges (configs, CSV, plots).
#pragma once

#include <numbers>

namespace hil::units {

inline constexpr double kRadPerDeg = std::numbers::pi / 180.0;
inline constexpr double kDegPerRad = 180.0 / std::numbers::pi;
inline constexpr double kPaPerMpa = 1e6;
inline constexpr double kPaPerKpa = 1e3;
inline constexpr double kM2PerMm2 = 1e-6;
inline constexpr double kM3PerL = 1e-3;

constexpr double deg_to_rad(double deg) { return deg * kRadPerDeg; }
constexpr double rad_to_deg(double rad) { return rad * kDegPerRad; }
constexpr double mpa_to_pa(double mpa) { return mpa * kPaPerMpa; }
constexpr double pa_to_mpa(double pa) { return pa / kPaPerMpa; }

}  // namespace hil::units
