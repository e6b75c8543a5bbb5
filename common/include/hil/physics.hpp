// The physics kernels, written once (physics.md sections 2-3): the burn law, the gas generator's
// chamber equation (forward for the plant, solved for the throat area for the controller's
// inverse model), the position servo's lag and rate limit, and the play operator of the gear
// backlash. The plant's effects and the controller's models call these; each keeps its own
// parameters. Dependency-free (the units header only) so the controller may use it. Every
// function is real-time safe: noexcept, no allocation.
#pragma once

#include <algorithm>
#include <cmath>

#include "hil/units.hpp"

namespace hil::physics {

// Burn law r = a (P / 1 MPa)^n with a in mm/s: the coefficient in SI for P in Pa,
// r [m/s] = a_si * P^n.
inline double burn_coeff_si(double a_mm_s_at_1mpa, double pressure_exponent) noexcept {
  return a_mm_s_at_1mpa * 1e-3 / std::pow(units::kPaPerMpa, pressure_exponent);
}

// P^n for a pressure that moves little from one call to the next (the chamber, step by step):
// the Taylor expansion about an anchor where P^n was computed exactly, of fourth order (relative
// error below n(n-1)(n-2)(n-3)(n-4)/120 d^5, 3e-12 for the burn law's n within d = 1 % of the
// anchor), with one exact pow to move the anchor when the pressure leaves that band. A pow costs
// as much as the rest of a plant step; the chamber moves 1 % in tens of steps.
struct PowNear {
  static constexpr double kBand = 0.01;  // relative distance from the anchor that moves it
  double anchor = 0;                     // 0: none yet
  double anchor_pow = 0;
  double inv_anchor = 0;

  // P^n and its first two Taylor coefficients at p (p^n ~ value + slope e + curve e^2 near p).
  struct Local {
    double value, slope, curve;
  };
  Local at(double p, double n) noexcept {
    double d = (p - anchor) * inv_anchor;
    if (!(std::abs(d) <= kBand && anchor > 0)) {  // also: no anchor yet, or p not finite
      anchor = p;
      anchor_pow = std::pow(p, n);
      inv_anchor = 1 / p;
      d = 0;
    }
    const double c1 = n, c2 = c1 * (n - 1) / 2, c3 = c2 * (n - 2) / 3, c4 = c3 * (n - 3) / 4;
    const double value = anchor_pow * (1 + d * (c1 + d * (c2 + d * (c3 + d * c4))));
    const double slope = anchor_pow * inv_anchor * (c1 + d * (2 * c2 + d * (3 * c3 + d * 4 * c4)));
    const double curve = anchor_pow * inv_anchor * inv_anchor * (c2 + d * (3 * c3 + d * 6 * c4));
    return {value, slope, curve};
  }
  double value(double p, double n) noexcept {
    double d = (p - anchor) * inv_anchor;
    if (!(std::abs(d) <= kBand && anchor > 0)) {
      anchor = p;
      anchor_pow = std::pow(p, n);
      inv_anchor = 1 / p;
      return anchor_pow;
    }
    const double c1 = n, c2 = c1 * (n - 1) / 2, c3 = c2 * (n - 2) / 3, c4 = c3 * (n - 3) / 4;
    return anchor_pow * (1 + d * (c1 + d * (c2 + d * (c3 + d * c4))));
  }
};

// A lumped chamber filled by an end-burning grain and emptied through a choked throat:
//   mdot_gen = rho_p Ab r, r = a_si P^n      mdot_out = P At / c*
//   dV/dt = g Ab r                           dP/dt = (RTc / V) (mdot_gen - mdot_out) - (P / V) dV/dt
// g (volume_growth) is the fraction of the burned grain's volume freed to the gas.
struct GasGenerator {
  double propellant_density_kg_m3 = 0;
  double burn_coeff_si = 0;      // a_si
  double pressure_exponent = 0;  // n
  double burning_area_m2 = 0;    // Ab
  double cstar_m_s = 0;          // c*
  double rtc_m2_s2 = 0;          // R*Tc
  double volume_growth = 1;      // g

  struct Rates {
    double dp_pa_s, dv_m3_s, mdot_gen_kg_s, mdot_out_kg_s;
  };
  // The chamber's rates at pressure p (with p^n given: the plant evaluates it cheaply near its
  // last value), free volume v and throat area at.
  Rates rates(double p_pa, double p_pow_n, double volume_m3, double throat_area_m2) const noexcept {
    const double burn_m_s = burn_coeff_si * p_pow_n;
    const double mdot_gen = propellant_density_kg_m3 * burning_area_m2 * burn_m_s;
    const double mdot_out = p_pa * throat_area_m2 / cstar_m_s;
    const double dv = volume_growth * burning_area_m2 * burn_m_s;
    return {(rtc_m2_s2 * (mdot_gen - mdot_out) - p_pa * dv) / volume_m3, dv, mdot_gen, mdot_out};
  }
  // Ab a_si c* (rho_p - g P / RTc): at equilibrium P At / c* = Ab a_si P^n (rho_p - g P / RTc),
  // so At = this P^(n-1) and P = (this / At)^(1 / (1 - n)).
  double equilibrium_factor(double p_pa) const noexcept {
    return burning_area_m2 * burn_coeff_si * cstar_m_s * (propellant_density_kg_m3 - volume_growth * p_pa / rtc_m2_s2);
  }
  // Throat area that holds p steady.
  double equilibrium_area_m2(double p_pa) const noexcept {
    return equilibrium_factor(p_pa) * std::pow(p_pa, pressure_exponent - 1);
  }
  // One fixed-point step towards the pressure a throat area holds steady (contracts fast because
  // P / RTc << rho_p).
  double equilibrium_pressure_step_pa(double p_pa, double throat_area_m2) const noexcept {
    return std::pow(equilibrium_factor(p_pa) / throat_area_m2, 1.0 / (1.0 - pressure_exponent));
  }
  // The chamber equation solved for the throat area, exactly: the area that makes the chamber at
  // pressure p and free volume v change at dp/dt.
  double throat_area_m2(double p_pa, double dpdt_pa_s, double volume_m3) const noexcept {
    return throat_area_m2(p_pa, std::pow(p_pa, pressure_exponent), dpdt_pa_s, volume_m3);
  }
  // The same with p^n given.
  double throat_area_m2(double p_pa, double p_pow_n, double dpdt_pa_s, double volume_m3) const noexcept {
    const double mdot_gen = propellant_density_kg_m3 * burning_area_m2 * burn_coeff_si * p_pow_n;
    const double mdot_out =
        mdot_gen * (1 - volume_growth * p_pa / (propellant_density_kg_m3 * rtc_m2_s2)) - volume_m3 / rtc_m2_s2 * dpdt_pa_s;
    return mdot_out * cstar_m_s / p_pa;
  }
};

// Position servo, one step: a first-order lag on the command, discretised exactly
// (keep = exp(-dt / tau), so the step size does not change the response), then a slew-rate limit
// of max_move per step.
inline double servo_keep(double dt_s, double time_constant_s) noexcept { return std::exp(-dt_s / time_constant_s); }
inline double servo_step_rad(double angle_rad, double cmd_rad, double keep, double max_move_rad) noexcept {
  const double lagged = cmd_rad + (angle_rad - cmd_rad) * keep;
  return angle_rad + std::clamp(lagged - angle_rad, -max_move_rad, max_move_rad);
}

// The play (backlash) operator: the follower stays where it is while the driver moves inside the
// gap, and is pushed by the flank it touches: follower in [driver - half_gap, driver + half_gap].
inline double play_rad(double follower_rad, double driver_rad, double half_gap_rad) noexcept {
  if (driver_rad - half_gap_rad > follower_rad) return driver_rad - half_gap_rad;  // the positive flank pushes
  if (driver_rad + half_gap_rad < follower_rad) return driver_rad + half_gap_rad;  // the negative flank pushes
  return follower_rad;
}

}  // namespace hil::physics
