// Effects outside the candidate list, for the "unexplained" tests: a combustion-driven pressure
// oscillation in the chamber (a limit cycle the lumped model cannot have), a gear's
// transmission error (a ripple periodic in the motor angle), and a valve that sticks (stick-slip). Their parameters have no defaults, so
// diagnose does not pick them up as user candidates: they stay truly unknown.
#include <cmath>
#include <numbers>

#include "hil/plant/registry.hpp"
#include "hil/units.hpp"

namespace hil::plant {

class ChamberOscillation final : public ScalarEffect<ChamberOscillation> {
 public:
  static constexpr std::string_view kKind = "test_chamber_oscillation";
  static constexpr Stage kStage = Stage::sensor;  // on the pressure, before the transducer's errors
  static constexpr ParamSpec kSpecs[] = {
      {"amplitude_kpa", 0, 1e3, false, false, kNaN, "oscillation amplitude"},
      {"frequency_hz", 0, 1e3, true, false, kNaN, "oscillation frequency"},
  };
  using ScalarEffect::ScalarEffect;
  void settle(std::span<double>, Signals&) const override {}
  void step(std::span<double>, Signals& s, double, Rng&) const noexcept override {
    s.p_meas_pa += value(0) * units::kPaPerKpa * std::sin(2 * std::numbers::pi * value(1) * s.t_s);
  }
};

HIL_REGISTER_EFFECT(ChamberOscillation, "test only: combustion pressure oscillation (not a candidate)")

// A gear's transmission error: the valve leads or lags the ideal gear by a ripple with one period
// per tooth of the motor's pinion, amplitude_deg sin(2 pi theta_motor / pitch_deg), after the backlash.
class GearRipple final : public ScalarEffect<GearRipple> {
 public:
  static constexpr std::string_view kKind = "test_gear_ripple";
  static constexpr Stage kStage = Stage::transmission;
  static constexpr ParamSpec kSpecs[] = {
      {"amplitude_deg", 0, 5, false, false, kNaN, "transmission error amplitude"},
      {"pitch_deg", 0, 90, true, false, kNaN, "motor angle per tooth"},
  };
  using ScalarEffect::ScalarEffect;
  void settle(std::span<double>, Signals& s) const override { apply(s); }
  void step(std::span<double>, Signals& s, double, Rng&) const noexcept override { apply(s); }

 private:
  void apply(Signals& s) const noexcept {
    const double error_rad =
        units::deg_to_rad(value(0)) * std::sin(2 * std::numbers::pi * s.theta_motor_rad / units::deg_to_rad(value(1)));
    s.theta_valve_rad += error_rad;
    s.theta_throat_rad = s.theta_valve_rad;
  }
};

HIL_REGISTER_EFFECT(GearRipple, "test only: a gear's transmission error, periodic in the motor angle (not a candidate)")

// Stick-slip: the valve holds where it stopped until the transmission has wound up by
// breakaway_deg against it (static friction), then slips to where the backlash would put it.
class StickSlip final : public ScalarEffect<StickSlip> {
 public:
  static constexpr std::string_view kKind = "test_stick_slip";
  static constexpr Stage kStage = Stage::transmission;
  static constexpr ParamSpec kSpecs[] = {
      {"breakaway_deg", 0, 5, false, false, kNaN, "wind-up of the transmission at which the stuck valve slips"},
  };
  using ScalarEffect::ScalarEffect;
  std::size_t state_size() const noexcept override { return 1; }
  void settle(std::span<double> x, Signals& s) const override { x[0] = s.theta_valve_rad; }
  void step(std::span<double> x, Signals& s, double, Rng&) const noexcept override {
    if (std::abs(s.theta_valve_rad - x[0]) > units::deg_to_rad(value(0))) x[0] = s.theta_valve_rad;
    s.theta_valve_rad = s.theta_throat_rad = x[0];
  }
};

HIL_REGISTER_EFFECT(StickSlip, "test only: a valve that sticks until the transmission winds up (not a candidate)")

}  // namespace hil::plant
