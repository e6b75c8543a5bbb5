// The nominal chamber of physics.md section 2 as the controller sees it.
#pragma once

#include <cmath>
#include <string>

#include "hil/ctl/controller.hpp"

namespace hil::test {

inline ctl::ChamberModel nominal_chamber() {
  ctl::ChamberModel m;
  m.propellant_density_kg_m3 = 1700;
  m.pressure_exponent = 0.35;
  m.burn_coeff_si = 0.005 / std::pow(1e6, 0.35);
  m.burning_area_m2 = 0.01;
  m.cstar_m_s = 900;
  m.rtc_m2_s2 = 352836;
  m.map_points = 2;
  m.map_angle_rad = {0, 30 * M_PI / 180};
  m.map_area_m2 = {40e-6, 140e-6};
  return m;
}

inline ctl::ControllerParams nominal_params(ctl::Compensation c, const char* compensator) {
  ctl::ControllerParams p;
  p.compensation = c;
  p.compensator = compensator;
  p.chamber = nominal_chamber();
  p.gap_known_rad = 1 * M_PI / 180;
  return p;
}

}  // namespace hil::test
