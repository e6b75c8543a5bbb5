// Candidate effect: the valve's zero differs from the motor's, so the throat sees a shifted angle.
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

  void settle(std::span<double>, Signals& s) const override { apply(s); }
  void step(std::span<double>, Signals& s, double, Rng&) const noexcept override { apply(s); }

 private:
  void apply(Signals& s) const noexcept { s.theta_throat_rad += units::deg_to_rad(value(0)); }
};

HIL_REGISTER_EFFECT(ValveOffset, "offset between the valve's zero and the motor's")

}  // namespace hil::plant
