// A gear's transmission error with its fit prior: analysis/README.md's worked example, verbatim.
// The valve leads or lags the ideal gear by a ripple with one period per tooth of the motor's
// pinion, amplitude_deg sin(2 pi theta_motor / pitch_deg), after the backlash.
#include <cmath>
#include <numbers>

#include "hil/plant/fit_prior.hpp"
#include "hil/plant/registry.hpp"
#include "hil/units.hpp"

namespace hil::plant {

class GearRipple final : public ScalarEffect<GearRipple> {
 public:
  static constexpr std::string_view kKind = "gear_ripple";  // its YAML block's name
  static constexpr Stage kStage = Stage::transmission;      // after the backlash
  static constexpr ParamSpec kSpecs[] = {
      // key (with unit), physical range, open ends, default (amplitude 0 = effect absent), doc
      {"amplitude_deg", 0, 5, false, false, 0.0, "transmission error amplitude"},
      {"pitch_deg", 0, 90, true, false, 6.0, "motor angle per tooth of the pinion (the drawing's)"},
  };
  using ScalarEffect::ScalarEffect;

  // How diagnose looks for it. The amplitude by LM from a few sizes. The pitch: the drawing's
  // 6 deg in the first form; in the second, searched on a 0.01 deg grid over 4-8 deg, because the
  // cost is rugged in a period (a wrong pitch puts the ripple out of phase a few teeth away).
  static FitPrior fit_prior(const FitEvidence&) {
    FitPrior p;
    p.description = "a gear's transmission error: a ripple periodic in the motor angle";
    p.params = {{.key = "amplitude_deg", .scale = 0.01, .starts = {0.05, 0.2, 0.5}},
                {.key = "pitch_deg", .lo = 4, .hi = 8, .grid = FitGrid::range, .grid_points = 401}};
    p.variants = {{"drawing's pitch", {"amplitude_deg"}}, {"pitch searched", {"amplitude_deg", "pitch_deg"}}};
    return p;
  }

  void settle(std::span<double>, Signals& s) const override { apply(s); }
  void step(std::span<double>, Signals& s, double, Rng&) const noexcept override { apply(s); }

 private:
  void apply(Signals& s) const noexcept {
    const double phase = 2 * std::numbers::pi * s.theta_motor_rad / units::deg_to_rad(value(1));
    s.theta_valve_rad += units::deg_to_rad(value(0)) * std::sin(phase);
    s.theta_throat_rad = s.theta_valve_rad;
  }
};

HIL_REGISTER_EFFECT(GearRipple, "a gear's transmission error, periodic in the motor angle")
HIL_REGISTER_FIT_PRIOR(GearRipple)

}  // namespace hil::plant
