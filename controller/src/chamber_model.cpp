#include "hil/ctl/chamber_model.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace hil::ctl {

void ChamberModel::validate() const {
  auto positive = [](double v, const char* name) {
    if (!(v > 0) || !std::isfinite(v)) throw std::invalid_argument(std::string("chamber model: ") + name + " must be > 0");
  };
  positive(propellant_density_kg_m3, "propellant density");
  positive(burn_coeff_si, "burn-rate coefficient");
  positive(burning_area_m2, "burning area");
  positive(cstar_m_s, "c*");
  positive(rtc_m2_s2, "R*Tc");
  if (!(volume_growth >= 0 && volume_growth <= 1)) throw std::invalid_argument("chamber model: volume growth must be in [0, 1]");
  if (!(pressure_exponent > 0 && pressure_exponent < 1)) {
    throw std::invalid_argument("chamber model: pressure exponent must be in (0, 1)");
  }
  if (map_points < 2 || map_points > kMaxMapPoints) {
    throw std::invalid_argument("chamber model: the throat map needs 2 to 16 points");
  }
  for (std::size_t i = 1; i < map_points; ++i) {
    if (!(map_angle_rad[i] > map_angle_rad[i - 1]) || map_area_m2[i] < map_area_m2[i - 1]) {
      throw std::invalid_argument("chamber model: the throat map must be monotone");
    }
  }
  if (!(map_area_m2[map_points - 1] > map_area_m2[0])) {
    throw std::invalid_argument("chamber model: the throat map must open");
  }
}

double ChamberModel::equilibrium_area_m2(double p_pa) const noexcept {
  return GasGenerator::equilibrium_area_m2(std::max(p_pa, 1.0));
}

double ChamberModel::throat_area_m2(double p_pa, double dpdt_pa_s, double volume_m3) const noexcept {
  return GasGenerator::throat_area_m2(std::max(p_pa, 1.0), dpdt_pa_s, volume_m3);
}

ChamberModel::Discharge ChamberModel::discharge(double p_pa, double dpdt_pa_s, double volume_m3, physics::PowNear& pow_near,
                                                const physics::ThroatAreaSolver& solver) const noexcept {
  p_pa = std::max(p_pa, 1.0);
  return {p_pa, solver.outflow_kg_s(p_pa, pow_near.value(p_pa, solver.pow_series), dpdt_pa_s, volume_m3)};
}

double ChamberModel::angle_for_area_rad(double area) const noexcept {
  if (area <= map_area_m2[0]) return map_angle_rad[0];
  for (std::size_t i = 1; i < map_points; ++i) {
    if (area <= map_area_m2[i]) {
      const double span = map_area_m2[i] - map_area_m2[i - 1];
      const double f = span > 0 ? (area - map_area_m2[i - 1]) / span : 0.0;
      return map_angle_rad[i - 1] + f * (map_angle_rad[i] - map_angle_rad[i - 1]);
    }
  }
  return map_angle_rad[map_points - 1];
}

double ChamberModel::map_slope_m2_per_rad(double p_pa) const noexcept {
  const double area = equilibrium_area_m2(p_pa);
  std::size_t i = 1;
  while (i + 1 < map_points && area > map_area_m2[i]) ++i;
  return (map_area_m2[i] - map_area_m2[i - 1]) / (map_angle_rad[i] - map_angle_rad[i - 1]);
}

double ChamberModel::time_constant_s(double p_pa, double volume_m3) const noexcept {
  return volume_m3 * cstar_m_s / (rtc_m2_s2 * equilibrium_area_m2(p_pa) * (1 - pressure_exponent));
}

double ChamberModel::gain_pa_per_rad(double p_pa) const noexcept {
  return p_pa / ((1 - pressure_exponent) * equilibrium_area_m2(p_pa)) * map_slope_m2_per_rad(p_pa);
}

double ChamberModel::volume_rate_m3_s(double p_pa) const noexcept {
  p_pa = std::max(p_pa, 1.0);
  return rates(p_pa, std::pow(p_pa, pressure_exponent), 1.0, 0.0).dv_m3_s;
}

}  // namespace hil::ctl
