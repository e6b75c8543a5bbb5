// The units a measurement file may name in its header, the one table every reader converts with
// (beside units.hpp's constants, which the rest of the code uses).
#pragma once

#include <array>
#include <cctype>
#include <optional>
#include <string_view>

#include "hil/units.hpp"

namespace hil::units {

// The units a measurement file may name in its header ("t_ms", "p [bar]"), the one table every
// reader converts with: each in SI of its quantity.
struct Unit {
  std::string_view name;      // as written, matched without regard to case
  std::string_view quantity;  // time, angle, pressure
  double si;                  // one of it in SI (s, rad, Pa)
};
inline constexpr std::array<Unit, 11> kUnits = {{
    {"s", "time", 1.0},
    {"ms", "time", 1e-3},
    {"us", "time", 1e-6},
    {"min", "time", 60.0},
    {"rad", "angle", 1.0},
    {"deg", "angle", kRadPerDeg},
    {"pa", "pressure", 1.0},
    {"kpa", "pressure", kPaPerKpa},
    {"mpa", "pressure", kPaPerMpa},
    {"bar", "pressure", 1e5},
    {"psi", "pressure", 6894.757293168361},  // the pound-force per square inch, exactly by definition
}};

inline bool same_letters(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(a[i])) != std::tolower(static_cast<unsigned char>(b[i]))) return false;
  return true;
}
inline std::optional<Unit> find_unit(std::string_view name) {
  for (const Unit& u : kUnits)
    if (same_letters(u.name, name)) return u;
  return std::nullopt;
}
// Factor from one unit to another of the same quantity (nullopt: unknown, or another quantity).
inline std::optional<double> conversion(std::string_view from, std::string_view to) {
  const auto a = find_unit(from), b = find_unit(to);
  if (!a || !b || a->quantity != b->quantity) return std::nullopt;
  return a->si / b->si;
}

}  // namespace hil::units
