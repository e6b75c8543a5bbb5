// The gas generator: a lumped chamber filled by an end-burning grain and emptied through the
// choked throat (physics.md section 2):
//   mdot_gen = rho_p * Ab * r,  r = a * (Pg / 1 MPa)^n     mdot_out = Pg * At / c*
//   dV/dt = Ab * r              dPg/dt = (R*Tc / V) * (mdot_gen - mdot_out) - (Pg / V) * dV/dt
// Integrated with classical RK4 at the loop step, the throat area held over the step. The
// state also carries the generated and discharged gas masses, integrated with the same stages,
// so the mass balance m_gas(t) - m_gas(0) = M_gen - M_out is checkable to integrator accuracy.
#include <algorithm>
#include <cmath>

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
      {"pressure_exponent", 0, 1, true, true, kNaN,
       "burn-rate pressure exponent n (n >= 1 has no stable steady state)"},
      {"burning_area_m2", 0, 1e3, true, false, kNaN, "burning surface Ab"},
      {"cstar_m_s", 0, 1e5, true, false, kNaN, "characteristic velocity c*"},
      {"rtc_m2_s2", 0, 1e8, true, false, kNaN, "R*Tc of the gas"},
      {"free_volume_l", 0, 1e5, true, false, kNaN, "free volume of the chamber at t = 0 (must be > 0)"},
  };
  explicit GasGenerator(std::vector<double> v)
      : ScalarEffect(std::move(v)),
        rho_(value(0)),
        // a in SI for Pg in Pa: r[m/s] = a_si * Pg^n
        a_si_(value(1) * 1e-3 / std::pow(units::kPaPerMpa, value(2))),
        n_(value(2)),
        ab_(value(3)),
        cstar_(value(4)),
        rtc_(value(5)),
        v0_(value(6) * units::kM3PerL) {}

  // State: chamber pressure, free volume, generated gas mass, discharged gas mass.
  std::size_t state_size() const noexcept override { return 4; }

  void settle(std::span<double> x, Signals& s) const override {
    // Equilibrium: Ab a P^n (rho_p - P/RTc) = P At / c*, solved by fixed point (contracts fast
    // because P/RTc << rho_p).
    double p = 1e6;
    for (int i = 0; i < 60; ++i) {
      p = std::pow(ab_ * a_si_ * cstar_ * (rho_ - p / rtc_) / s.throat_area_m2, 1.0 / (1.0 - n_));
    }
    x[0] = p;
    x[1] = v0_;
    x[2] = x[3] = 0;
    const Rates r = rates(p, v0_, s.throat_area_m2);
    write(x, s, r.mdot_gen, r.mdot_out);
  }

  void step(std::span<double> x, Signals& s, double dt_s, Rng&) const noexcept override {
    const double at = s.throat_area_m2;
    const double p = x[0], v = x[1];
    const Rates k1 = rates(p, v, at);
    const Rates k2 = rates(p + 0.5 * dt_s * k1.dp, v + 0.5 * dt_s * k1.dv, at);
    const Rates k3 = rates(p + 0.5 * dt_s * k2.dp, v + 0.5 * dt_s * k2.dv, at);
    const Rates k4 = rates(p + dt_s * k3.dp, v + dt_s * k3.dv, at);
    auto avg = [](double a, double b, double c, double d) { return (a + 2 * b + 2 * c + d) / 6; };
    const double mdot_gen = avg(k1.mdot_gen, k2.mdot_gen, k3.mdot_gen, k4.mdot_gen);
    const double mdot_out = avg(k1.mdot_out, k2.mdot_out, k3.mdot_out, k4.mdot_out);
    x[0] = std::max(p + dt_s * avg(k1.dp, k2.dp, k3.dp, k4.dp), kMinPressurePa);
    x[1] = v + dt_s * avg(k1.dv, k2.dv, k3.dv, k4.dv);
    x[2] += dt_s * mdot_gen;
    x[3] += dt_s * mdot_out;
    write(x, s, mdot_gen, mdot_out);
  }

 private:
  static constexpr double kMinPressurePa = 1.0;  // keeps P^n defined; far below any operating point
  struct Rates {
    double dp, dv, mdot_gen, mdot_out;
  };
  Rates rates(double p, double v, double at) const noexcept {
    p = std::max(p, kMinPressurePa);
    const double burn_m_s = a_si_ * std::pow(p, n_);
    const double mdot_gen = rho_ * ab_ * burn_m_s;
    const double mdot_out = p * at / cstar_;
    const double dv = ab_ * burn_m_s;
    return {(rtc_ * (mdot_gen - mdot_out) - p * dv) / v, dv, mdot_gen, mdot_out};
  }
  static void write(std::span<const double> x, Signals& s, double mdot_gen, double mdot_out) noexcept {
    s.p_chamber_pa = x[0];
    s.volume_m3 = x[1];
    s.mdot_gen_kg_s = mdot_gen;
    s.mdot_out_kg_s = mdot_out;
  }
  double rho_, a_si_, n_, ab_, cstar_, rtc_, v0_;
};

HIL_REGISTER_EFFECT(GasGenerator, "lumped gas-generator chamber with end-burning grain and choked throat")

}  // namespace hil::plant
