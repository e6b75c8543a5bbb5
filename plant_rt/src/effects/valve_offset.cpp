// Candidate effect: the valve's zero differs from the motor's, so the throat sees a shifted angle.
#include <cmath>

#include "hil/plant/fit_prior.hpp"
#include "hil/plant/registry.hpp"
#include "hil/units.hpp"

namespace hil::plant {

class ValveOffset final : public ScalarEffect<ValveOffset> {
 public:
  static constexpr std::string_view kKind = "valve_offset";
  static constexpr Stage kStage = Stage::valve;
  static constexpr ParamSpec kSpecs[] = {
      {"offset_deg", -45, 45, false, false, kNaN, "angle the throat sees minus the valve angle"},
  };
  using ScalarEffect::ScalarEffect;

  // How diagnose finds it (fit_prior.hpp): an offset either way from zero.
  static FitPrior fit_prior(const FitEvidence& ev) {
    const double v = ev.model_value("valve_offset", "offset_deg");
    FitPrior p;
    p.description = "the valve's zero differs from the motor's, so the throat sees a shifted angle";
    p.params = {{.key = "offset_deg",
                 .neutral = 0,
                 .lo = -10,
                 .hi = 10,
                 .scale = 0.2,
                 .starts = {std::isfinite(v) ? v : 0.0, -1.0, 1.0}}};
    p.variants = {{"offset", {"offset_deg"}}};
    return p;
  }

  void settle(std::span<double>, Signals& s) const override { apply(s); }
  void step(std::span<double>, Signals& s, double, Rng&) const noexcept override { apply(s); }

 private:
  void apply(Signals& s) const noexcept { s.theta_throat_rad += units::deg_to_rad(value(0)); }
};

HIL_REGISTER_EFFECT(ValveOffset, "offset between the valve's zero and the motor's")
HIL_REGISTER_FIT_PRIOR(ValveOffset)

}  // namespace hil::plant
