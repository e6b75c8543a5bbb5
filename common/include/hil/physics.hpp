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

  // The expansion's coefficients for one exponent: n, n(n-1)/2, ... (binomial), set once by a
  // caller that evaluates P^n every period rather than on each call (the /3 is a division).
  struct Series {
    double n, c1, c2, c3, c4;
  };
  static Series series(double n) noexcept {
    const double c1 = n, c2 = c1 * (n - 1) / 2, c3 = c2 * (n - 2) / 3, c4 = c3 * (n - 3) / 4;
    return {n, c1, c2, c3, c4};
  }

  // P^n and its first two Taylor coefficients at p (p^n ~ value + slope e + curve e^2 near p).
  struct Local {
    double value, slope, curve;
  };
  Local at(double p, const Series& k) noexcept {
    double d = (p - anchor) * inv_anchor;
    if (!(std::abs(d) <= kBand && anchor > 0)) {  // also: no anchor yet, or p not finite
      anchor = p;
      anchor_pow = std::pow(p, k.n);
      inv_anchor = 1 / p;
      d = 0;
    }
    const double value = anchor_pow * (1 + d * (k.c1 + d * (k.c2 + d * (k.c3 + d * k.c4))));
    const double slope = anchor_pow * inv_anchor * (k.c1 + d * (2 * k.c2 + d * (3 * k.c3 + d * 4 * k.c4)));
    const double curve = anchor_pow * inv_anchor * inv_anchor * (k.c2 + d * (3 * k.c3 + d * 6 * k.c4));
    return {value, slope, curve};
  }
  Local at(double p, double n) noexcept { return at(p, series(n)); }
  double value(double p, const Series& k) noexcept {
    double d = (p - anchor) * inv_anchor;
    if (!(std::abs(d) <= kBand && anchor > 0)) {
      anchor = p;
      anchor_pow = std::pow(p, k.n);
      inv_anchor = 1 / p;
      return anchor_pow;
    }
    return anchor_pow * (1 + d * (k.c1 + d * (k.c2 + d * (k.c3 + d * k.c4))));
  }
  double value(double p, double n) noexcept { return value(p, series(n)); }
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
  double throat_area_m2(double p_pa, double p_pow_n, double dpdt_pa_s, double volume_m3) const noexcept;
};

// GasGenerator::throat_area_m2 for a caller that solves it every period (the robust observer):
// the constant factors, and the two divisions among them, taken once.
struct ThroatAreaSolver {
  double gen_per_pn = 0;   // rho_p Ab a_si: generated mass flow per P^n
  double kept_per_pa = 0;  // g / (rho_p RTc): the share of it that stays to fill the freed volume, per Pa
  double inv_rtc = 0;      // 1 / RTc
  double cstar_m_s = 0;
  PowNear::Series pow_series{};  // for P^n

  ThroatAreaSolver() = default;
  explicit ThroatAreaSolver(const GasGenerator& g) noexcept
      : gen_per_pn(g.propellant_density_kg_m3 * g.burning_area_m2 * g.burn_coeff_si),
        kept_per_pa(g.volume_growth / (g.propellant_density_kg_m3 * g.rtc_m2_s2)),
        inv_rtc(1 / g.rtc_m2_s2),
        cstar_m_s(g.cstar_m_s),
        pow_series(PowNear::series(g.pressure_exponent)) {}
  // The area through which the chamber at pressure p (p^n given), free volume v discharges what
  // makes it change at dp/dt. In two halves for a caller that needs the second for only some
  // periods: the discharge, then the area that passes it at p.
  double area_m2(double p_pa, double p_pow_n, double dpdt_pa_s, double volume_m3) const noexcept {
    return area_for_outflow_m2(outflow_kg_s(p_pa, p_pow_n, dpdt_pa_s, volume_m3), p_pa);
  }
  // mdot_out = mdot_gen (1 - g P / (rho_p RTc)) - V / RTc dP/dt
  double outflow_kg_s(double p_pa, double p_pow_n, double dpdt_pa_s, double volume_m3) const noexcept {
    const double mdot_gen = gen_per_pn * p_pow_n;
    return mdot_gen * (1 - kept_per_pa * p_pa) - volume_m3 * inv_rtc * dpdt_pa_s;
  }
  double area_for_outflow_m2(double mdot_out_kg_s, double p_pa) const noexcept { return mdot_out_kg_s * cstar_m_s / p_pa; }
};

inline double GasGenerator::throat_area_m2(double p_pa, double p_pow_n, double dpdt_pa_s, double volume_m3) const noexcept {
  return ThroatAreaSolver(*this).area_m2(p_pa, p_pow_n, dpdt_pa_s, volume_m3);
}

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
// half_gap_rad >= 0 (or NaN: then, as for a NaN driver, the follower stays). Written without
// branches (a min, then a max) so that T may also be a GCC vector of doubles: the gap fit runs
// several candidate gaps side by side through this same operator. In place and by reference, so
// that a wide vector never crosses a call by value (its ABI differs with and without AVX).
template <class T>
[[gnu::always_inline]] inline void play_in_place(T& follower_rad, const T& driver_rad, const T& half_gap_rad) noexcept {
  const T upper = driver_rad + half_gap_rad, lower = driver_rad - half_gap_rad;
  const T held = upper < follower_rad ? upper : follower_rad;  // the negative flank pushes
  follower_rad = lower > held ? lower : held;                  // the positive flank pushes
}
inline double play_rad(double follower_rad, double driver_rad, double half_gap_rad) noexcept {
  play_in_place(follower_rad, driver_rad, half_gap_rad);
  return follower_rad;
}

}  // namespace hil::physics
