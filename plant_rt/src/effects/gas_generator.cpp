// The gas generator: a lumped chamber filled by an end-burning grain and emptied through the
// choked throat (physics.md section 2; the equation is physics::GasGenerator's, shared with the
// controller's model):
//   mdot_gen = rho_p * Ab * r,  r = a * (Pg / 1 MPa)^n     mdot_out = Pg * At / c*
//   dV/dt = g * Ab * r          dPg/dt = (R*Tc / V) * (mdot_gen - mdot_out) - (Pg / V) * dV/dt
// g (volume_growth) is 1 for an end-burning grain in a closed case (physics.md); 0 keeps the free
// volume constant (a bench simulator, a fed generator, or an hour-long soak a real grain would
// not survive).
// Integrated at the loop step, the throat area held over the step, by the fourth-order Taylor
// series of the pressure (classical RK4 where the pressure moves more than 1 % in one step). The
// state also carries the generated and discharged gas masses, integrated with the same series,
// so the mass balance m_gas(t) - m_gas(0) = M_gen - M_out is checkable to integrator accuracy.
#include <algorithm>
#include <cmath>

#include "hil/physics.hpp"
#include "hil/plant/fit_prior.hpp"
#include "hil/plant/registry.hpp"
#include "hil/units.hpp"

namespace hil::plant {

class GasGenerator final : public ScalarEffect<GasGenerator> {
 public:
  static constexpr std::string_view kKind = "gas_generator";
  static constexpr Stage kStage = Stage::chamber;
  static constexpr ParamSpec kSpecs[] = {
      {"propellant_density_kg_m3", 0, 1e5, true, false, kNaN, "propellant density rho_p"},
      {"burn_rate_mm_s_at_1mpa", 0, 1e4, true, false, kNaN, "burn-rate coefficient a, r = a (Pg/1 MPa)^n"},
      {"pressure_exponent", 0, 1, true, true, kNaN, "burn-rate pressure exponent n (n >= 1 has no stable steady state)"},
      {"burning_area_m2", 0, 1e3, true, false, kNaN, "burning surface Ab"},
      {"cstar_m_s", 0, 1e5, true, false, kNaN, "characteristic velocity c*"},
      {"rtc_m2_s2", 0, 1e8, true, false, kNaN, "R*Tc of the gas"},
      {"free_volume_l", 0, 1e5, true, false, kNaN, "free volume of the chamber at t = 0 (must be > 0)"},
      {"volume_growth", 0, 1, false, false, 1.0, "fraction of the burned grain's volume freed to the gas"},
  };
  // How diagnose finds another propellant (fit_prior.hpp; candidate burn_rate, refitting this
  // block): the burn-rate coefficient a, the exponent n, or both.
  static FitPrior fit_prior(const FitEvidence& ev) {
    const double a = ev.model_value("gas_generator", "burn_rate_mm_s_at_1mpa");
    const double n = ev.model_value("gas_generator", "pressure_exponent");
    FitPrior p;
    p.candidate = "burn_rate";
    p.description = "the propellant's burn-rate coefficient a or exponent n differs (refits gas_generator)";
    p.refit = true;
    p.params = {{.key = "burn_rate_mm_s_at_1mpa", .lo = 0.5 * a, .hi = 2.0 * a, .scale = 0.01 * a, .starts = {a}},
                {.key = "pressure_exponent", .lo = 0.05, .hi = 0.9, .scale = 0.005, .starts = {n}}};
    p.variants = {{"coefficient a", {"burn_rate_mm_s_at_1mpa"}},
                  {"exponent n", {"pressure_exponent"}},
                  {"a and n", {"burn_rate_mm_s_at_1mpa", "pressure_exponent"}}};
    return p;
  }

  explicit GasGenerator(std::vector<double> v)
      : ScalarEffect(std::move(v)),
        gas_{value(0), physics::burn_coeff_si(value(1), value(2)), value(2), value(3), value(4), value(5), value(7)},
        v0_(value(6) * units::kM3PerL),
        pow_series_(physics::PowNear::series(gas_.pressure_exponent)) {}

  // State: chamber pressure, free volume, generated gas mass, discharged gas mass; then the
  // anchor of P^n's expansion (physics::PowNear: anchor, its P^n, its inverse).
  std::size_t state_size() const noexcept override { return 7; }

  void settle(std::span<double> x, Signals& s) const override {
    // Equilibrium: Ab a P^n (rho_p - g P/RTc) = P At / c*, solved by fixed point.
    double p = 1e6;
    for (int i = 0; i < 60; ++i) {
      const double next = gas_.equilibrium_pressure_step_pa(p, s.throat_area_m2);
      const bool converged = std::abs(next - p) <= 1e-12 * next;
      p = next;
      if (converged) break;
    }
    x[0] = p;
    x[1] = v0_;
    x[2] = x[3] = 0;
    x[4] = x[5] = x[6] = 0;
    const Rates r = rates(p, std::pow(p, gas_.pressure_exponent), v0_, s.throat_area_m2);
    write(x, s, r.mdot_gen_kg_s, r.mdot_out_kg_s);
  }

  void step(std::span<double> x, Signals& s, double dt_s, Rng& rng) const noexcept override {
    const double at = s.throat_area_m2;
    const double p0 = std::max(x[0], kMinPressurePa), v = x[1];
    // P^n at p0 and its Taylor coefficients there, from the expansion about the anchor.
    physics::PowNear pow_near{x[4], x[5], x[6]};
    const physics::PowNear::Local pn = pow_near.at(p0, pow_series_);
    x[4] = pow_near.anchor, x[5] = pow_near.anchor_pow, x[6] = pow_near.inv_anchor;
    // Within a step P moves a fraction of a percent: P^n from its second-order Taylor expansion
    // about p0 (error ~ 1e-7 relative at 1 %). With it, V dP/dt = F(e) is a cubic in e = P - p0
    // and dV/dt = G(e) a quadratic. Only the At terms of F wait for the throat area, which
    // arrives last.
    const Cubic f = cubic(p0, at, pn);
    // Fourth-order Taylor series of e(t) about the step's start, its derivatives in closed form
    // (F = c0 + c1 e + ..., G = g0 + g1 e + ..., subscripts derivatives by e, y = dt / V):
    //   V e1 = F,  V^2 e2 = F Q with Q = F_e - G,  V^3 e3 = F R with R = Q (F_e - 2G) + F Q_e,
    //   V^4 e4 = F (R (F_e - 3G) + F R_e).
    // The same order as classical RK4 (identical on a linear chamber, where both are the
    // exponential's fourth-order expansion), but as products side by side rather than four
    // dependent stages: the chain from the throat area to the pressure is about half as long.
    const double y = dt_s / v;
    const double g0 = f.dv_per_pn * pn.value, g1 = f.dv_per_pn * pn.slope, g2 = f.dv_per_pn * pn.curve;
    const double q = f.c1 - g0, q_e = 2 * f.c2 - g1, q_ee = 6 * f.c3 - 2 * g2;
    const double r = q * (f.c1 - 2 * g0) + f.c0 * q_e;
    const double r_e = q_e * (f.c1 - 2 * g0) + q * (2 * f.c2 - 2 * g1) + f.c1 * q_e + f.c0 * q_ee;
    const double s4 = r * (f.c1 - 3 * g0) + f.c0 * r_e;
    // |q y| is the step in the chamber's own time constants (q / V is the local rate, -1/tau). An
    // explicit step of many time constants amplifies rather than damps (a 3 mL chamber at 1 ms
    // flipped between 1 Pa and 0.37 MPa every period): such a step is split. The nominal chamber
    // (tau ~ 56 ms) at 1 ms is at 0.02, never split, so its numbers do not change.
    if (!(std::abs(q * y) <= kMaxStepTaus)) [[unlikely]]
      return step_split(x, s, dt_s, std::abs(q * y), rng);
    const double c0y = f.c0 * y, y2 = y * y;
    const double e = c0y * ((1 + (0.5 * y) * q) + y2 * (r * (1.0 / 6) + (y * (1.0 / 24)) * s4));
    if (!(std::abs(e) <= 0.01 * p0) || p0 + e < kMinPressurePa) return step_rk4(x, s, dt_s, p0, v, at, f, pn);
    // The step's means of e and e^2 (one order less: they feed the volume and the mass flows,
    // which the pressure sees only through the next step's V) give the mean P and P^n.
    const double mean_e = c0y * (0.5 + y * (q * (1.0 / 6) + y * (r * (1.0 / 24))));
    const double mean_e2 = c0y * c0y * (1.0 / 3 + y * q * 0.25);
    const double pn_avg = pn.value + pn.slope * mean_e + pn.curve * mean_e2;
    const double mdot_gen = f.gen_per_pn * pn_avg;
    const double mdot_out = f.out_per_p * (p0 + mean_e);
    x[0] = p0 + e;
    x[1] = v + dt_s * f.dv_per_pn * pn_avg;
    x[2] += dt_s * mdot_gen;
    x[3] += dt_s * mdot_out;
    write(x, s, mdot_gen, mdot_out);
  }

 private:
  // V dP/dt = c0 + c1 e + c2 e^2 + c3 e^3 about p0, and what it is made of.
  struct Cubic {
    double c0, c1, c2, c3;
    double gen_per_pn, dv_per_pn, out_per_p;
  };
  Cubic cubic(double p0, double at, const physics::PowNear::Local& pn) const noexcept {
    const double gen_per_pn = gas_.propellant_density_kg_m3 * gas_.burning_area_m2 * gas_.burn_coeff_si;
    const double dv_per_pn = gas_.volume_growth * gas_.burning_area_m2 * gas_.burn_coeff_si;
    const double pn_factor = gas_.rtc_m2_s2 * gen_per_pn - dv_per_pn * p0;  // what multiplies P^n at p0
    const double out_per_p = at / gas_.cstar_m_s;
    const double b = gas_.rtc_m2_s2 * out_per_p;
    return {pn.value * pn_factor - b * p0,
            pn.slope * pn_factor - pn.value * dv_per_pn - b,
            pn.curve * pn_factor - pn.slope * dv_per_pn,
            -pn.curve * dv_per_pn,
            gen_per_pn,
            dv_per_pn,
            out_per_p};
  }

  // A stiff step (a small or fast chamber, or a long step: a measurement's gap) as n equal steps
  // of at most kMaxStepTaus/2 time constants; the step's flows are the means over them. Beyond
  // kMaxSubsteps the chamber is too fast to follow at any sensible cost: its pressure becomes NaN,
  // which compare reports as a diverging model with its time, instead of a plausible wrong number.
  void step_split(std::span<double> x, Signals& s, double dt_s, double step_taus, Rng& rng) const noexcept {
    const double parts = std::ceil(2 * step_taus / kMaxStepTaus);
    if (!(parts <= kMaxSubsteps)) {
      x[0] = kNaN;
      write(x, s, kNaN, kNaN);
      return;
    }
    const int n = static_cast<int>(parts);
    const double gen0 = x[2], out0 = x[3], h = dt_s / n;
    for (int i = 0; i < n; ++i) step(x, s, h, rng);
    write(x, s, (x[2] - gen0) / dt_s, (x[3] - out0) / dt_s);
  }

  // Classical RK4 for the steps the series does not cover (P moving more than 1 % in one step:
  // long steps, or far from equilibrium); a stage's P^n is exact once it leaves the expansion's band.
  void step_rk4(std::span<double> x, Signals& s, double dt_s, double p0, double v, double at, const Cubic& f,
                const physics::PowNear::Local& pn) const noexcept {
    const double n = gas_.pressure_exponent;
    const double limit = 0.01 * p0;
    struct Stage {
      double dp_pa_s, pn;
      double e_next;  // the next stage's P - p0
    };
    auto stage = [&](double e, double v_k, double ahead_s) noexcept -> Stage {
      if (std::abs(e) > limit || p0 + e < kMinPressurePa) {
        const double p = std::max(p0 + e, kMinPressurePa), pn_exact = std::pow(p, n);
        const double dp = gas_.rates(p, pn_exact, v_k, at).dp_pa_s;
        return {dp, pn_exact, ahead_s * dp};
      }
      const double inv_v = 1 / v_k;
      const double vdp = (f.c0 + f.c1 * e) + e * e * (f.c2 + f.c3 * e);
      return {vdp * inv_v, pn.value + (pn.slope + pn.curve * e) * e, vdp * (ahead_s * inv_v)};
    };
    const double h = 0.5 * dt_s;
    const Stage k1 = stage(0, v, h);
    const Stage k2 = stage(k1.e_next, v + h * f.dv_per_pn * k1.pn, h);
    const Stage k3 = stage(k2.e_next, v + h * f.dv_per_pn * k2.pn, dt_s);
    const Stage k4 = stage(k3.e_next, v + dt_s * f.dv_per_pn * k3.pn, 0);
    auto avg = [](double a, double b, double c, double d) { return (a + 2 * b + 2 * c + d) / 6; };
    const double pn_avg = avg(k1.pn, k2.pn, k3.pn, k4.pn);
    // The discharge at each stage's pressure: p0 + e_k, the e_k of the stages above.
    const double p_avg = p0 + (2 * k1.e_next + 2 * k2.e_next + k3.e_next) / 6;
    const double mdot_gen = f.gen_per_pn * pn_avg;
    const double mdot_out = f.out_per_p * p_avg;
    x[0] = std::max(p0 + (k1.dp_pa_s + 2 * k2.dp_pa_s + 2 * k3.dp_pa_s + k4.dp_pa_s) * (dt_s / 6), kMinPressurePa);
    x[1] = v + dt_s * f.dv_per_pn * pn_avg;
    x[2] += dt_s * mdot_gen;
    x[3] += dt_s * mdot_out;
    write(x, s, mdot_gen, mdot_out);
  }

  static constexpr double kMinPressurePa = 1.0;  // keeps P^n defined; far below any operating point
  // RK4's stability bound on a decay is 2.79 time constants a step; 1 keeps it accurate as well.
  static constexpr double kMaxStepTaus = 1.0;
  static constexpr double kMaxSubsteps = 100000;
  using Rates = physics::GasGenerator::Rates;
  Rates rates(double p, double pn, double v, double at) const noexcept { return gas_.rates(p, pn, v, at); }
  static void write(std::span<const double> x, Signals& s, double mdot_gen, double mdot_out) noexcept {
    s.p_chamber_pa = x[0];
    s.volume_m3 = x[1];
    s.mdot_gen_kg_s = mdot_gen;
    s.mdot_out_kg_s = mdot_out;
  }
  physics::GasGenerator gas_;
  double v0_;
  physics::PowNear::Series pow_series_;  // P^n's expansion coefficients, set once
};

HIL_REGISTER_EFFECT(GasGenerator, "lumped gas-generator chamber with end-burning grain and choked throat")
HIL_REGISTER_FIT_PRIOR(GasGenerator)

}  // namespace hil::plant
