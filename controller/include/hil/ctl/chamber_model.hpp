// The nominal gas generator as the controller designer sees it: the numbers the KI(Pg0, V0)
// schedule linearises (physics.md section 2) and the static map the robust observer uses to turn
// an equilibrium pressure into a valve angle. A model, not the truth: the plant may differ.
// All methods are real-time safe (noexcept, no allocation).
#pragma once

#include <array>
#include <cstddef>

#include "hil/physics.hpp"

namespace hil::ctl {

// The gas generator's parameters and equation are physics::GasGenerator's (the plant's too); this
// adds the throat map and the linearisation the controller designs with. Pressures below 1 Pa are
// taken as 1 Pa (the laws have p^(n-1)).
struct ChamberModel : physics::GasGenerator {
  static constexpr std::size_t kMaxMapPoints = 16;
  std::array<double, kMaxMapPoints> map_angle_rad{};  // throat map, increasing angles
  std::array<double, kMaxMapPoints> map_area_m2{};    // non-decreasing areas
  std::size_t map_points = 0;

  // Throws std::invalid_argument naming the bad value.
  void validate() const;

  // Throat area that holds `p_pa` steady: Ab a c* (rho_p - g p/RTc) p^(n-1).
  double equilibrium_area_m2(double p_pa) const noexcept;
  // Valve angle whose throat holds `p_pa` steady (inverse map, clamped to the table).
  double valve_angle_rad(double p_pa) const noexcept { return angle_for_area_rad(equilibrium_area_m2(p_pa)); }
  // Inverse of the throat map, clamped to the table.
  double angle_for_area_rad(double area_m2) const noexcept;
  // The chamber equation solved for the throat area, exactly (no linearisation): the area that
  // makes the chamber at pressure p, volume v change at dp/dt.
  double throat_area_m2(double p_pa, double dpdt_pa_s, double volume_m3) const noexcept;
  // The same in two halves, for a caller that solves the equation every period but needs the
  // area for only some periods (the robust observer's fit history): the discharge at (p, dp/dt,
  // v), with p^n from an expansion about an anchor the caller keeps and the equation's constants
  // from a solver the caller built once from this model; later, the area of that discharge.
  struct Discharge {
    double p_pa = 0;  // as clamped
    double outflow_kg_s = 0;
  };
  Discharge discharge(double p_pa, double dpdt_pa_s, double volume_m3, physics::PowNear& pow_near,
                      const physics::ThroatAreaSolver& solver) const noexcept;
  static double throat_area_m2(const Discharge& d, const physics::ThroatAreaSolver& solver) noexcept {
    return solver.area_for_outflow_m2(d.outflow_kg_s, d.p_pa);
  }
  // Slope of the map at the angle whose area holds `p_pa` steady.
  double map_slope_m2_per_rad(double p_pa) const noexcept;
  // Linearised chamber time constant tau = V c* / (RTc At0 (1 - n)).
  double time_constant_s(double p_pa, double volume_m3) const noexcept;
  // Static gain |dP/dtheta_V| = P / ((1 - n) At0) * dAt/dtheta_V.
  double gain_pa_per_rad(double p_pa) const noexcept;
  // Growth of the free volume as the grain burns: g Ab a p^n.
  double volume_rate_m3_s(double p_pa) const noexcept;
};

}  // namespace hil::ctl
