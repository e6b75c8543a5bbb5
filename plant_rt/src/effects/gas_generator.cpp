// The gas generator: a lumped chamber filled by an end-burning grain and emptied through the
// choked throat (physics.md section 2; the equation is physics::GasGenerator's, shared with the
// controller's model):
//   mdot_gen = rho_p * Ab * r,  r = a * (Pg / 1 MPa)^n     mdot_out = Pg * At / c*
//   dV/dt = g * Ab * r          dPg/dt = (R*Tc / V) * (mdot_gen - mdot_out) - (Pg / V) * dV/dt
// g (volume_growth) is 1 for an end-burning grain in a closed case (physics.md); 0 keeps the free
// volume constant (a bench simulator, a fed generator, or an hour-long soak a real grain would
// not survive).
// Integrated with classical RK4 at the loop step, the throat area held over the step. The
// state also carries the generated and discharged gas masses, integrated with the same stages,
// so the mass balance m_gas(t) - m_gas(0) = M_gen - M_out is checkable to integrator accuracy.
#include <algorithm>
#include <cmath>

#include "hil/physics.hpp"
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
  explicit GasGenerator(std::vector<double> v)
      : ScalarEffect(std::move(v)),
        gas_{value(0), physics::burn_coeff_si(value(1), value(2)), value(2), value(3), value(4), value(5), value(7)},
        v0_(value(6) * units::kM3PerL) {}

  // State: chamber pressure, free volume, generated gas mass, discharged gas mass; then P^n and
  // the pressure it was computed for. P^n is computed where the pressure is written, so the pow
  // overlaps the rest of the period instead of heading the next step's chain.
  std::size_t state_size() const noexcept override { return 6; }

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
    remember_pow(x);
    const Rates r = rates(p, std::pow(p, gas_.pressure_exponent), v0_, s.throat_area_m2);
    write(x, s, r.mdot_gen_kg_s, r.mdot_out_kg_s);
  }

  void step(std::span<double> x, Signals& s, double dt_s, Rng&) const noexcept override {
    const double at = s.throat_area_m2;
    const double p = std::max(x[0], kMinPressurePa), v = x[1];
    const double pn = x[5] == p ? x[4] : std::pow(p, gas_.pressure_exponent);
    const Rates k1 = rates(p, pn, v, at);
    const Rates k2 = rates(p + 0.5 * dt_s * k1.dp_pa_s, pn, p, v + 0.5 * dt_s * k1.dv_m3_s, at);
    const Rates k3 = rates(p + 0.5 * dt_s * k2.dp_pa_s, pn, p, v + 0.5 * dt_s * k2.dv_m3_s, at);
    const Rates k4 = rates(p + dt_s * k3.dp_pa_s, pn, p, v + dt_s * k3.dv_m3_s, at);
    auto avg = [](double a, double b, double c, double d) { return (a + 2 * b + 2 * c + d) / 6; };
    const double mdot_gen = avg(k1.mdot_gen_kg_s, k2.mdot_gen_kg_s, k3.mdot_gen_kg_s, k4.mdot_gen_kg_s);
    const double mdot_out = avg(k1.mdot_out_kg_s, k2.mdot_out_kg_s, k3.mdot_out_kg_s, k4.mdot_out_kg_s);
    x[0] = std::max(p + dt_s * avg(k1.dp_pa_s, k2.dp_pa_s, k3.dp_pa_s, k4.dp_pa_s), kMinPressurePa);
    x[1] = v + dt_s * avg(k1.dv_m3_s, k2.dv_m3_s, k3.dv_m3_s, k4.dv_m3_s);
    x[2] += dt_s * mdot_gen;
    x[3] += dt_s * mdot_out;
    remember_pow(x);
    write(x, s, mdot_gen, mdot_out);
  }

 private:
  static constexpr double kMinPressurePa = 1.0;  // keeps P^n defined; far below any operating point
  using Rates = physics::GasGenerator::Rates;
  // The later RK stages differ from the step's start by a fraction of a percent: P^n from a
  // second-order Taylor expansion about p0 (error ~ 1e-7 relative at 1 %), exact pow beyond.
  Rates rates(double p, double p0n, double p0, double v, double at) const noexcept {
    p = std::max(p, kMinPressurePa);
    const double d = (p - p0) / p0;
    if (std::abs(d) > 0.01) return rates(p, std::pow(p, gas_.pressure_exponent), v, at);
    return rates(p, p0n * (1 + gas_.pressure_exponent * d * (1 + 0.5 * (gas_.pressure_exponent - 1) * d)), v, at);
  }
  Rates rates(double p, double pn, double v, double at) const noexcept { return gas_.rates(p, pn, v, at); }
  void remember_pow(std::span<double> x) const noexcept {
    x[5] = std::max(x[0], kMinPressurePa);
    x[4] = std::pow(x[5], gas_.pressure_exponent);
  }
  static void write(std::span<const double> x, Signals& s, double mdot_gen, double mdot_out) noexcept {
    s.p_chamber_pa = x[0];
    s.volume_m3 = x[1];
    s.mdot_gen_kg_s = mdot_gen;
    s.mdot_out_kg_s = mdot_out;
  }
  physics::GasGenerator gas_;
  double v0_;
};

HIL_REGISTER_EFFECT(GasGenerator, "lumped gas-generator chamber with end-burning grain and choked throat")

}  // namespace hil::plant
