// Candidate effect: the gap differs from the model's and/or changes during the run:
//   gap(t) = gap_deg + (t >= step_time_s ? step_deg : 0) + drift_deg_per_s * t,  never below 0.
#include <algorithm>

#include "hil/plant/registry.hpp"
#include "hil/units.hpp"

namespace hil::plant {

class BacklashChange final : public ScalarEffect<BacklashChange> {
 public:
  static constexpr std::string_view kKind = "backlash_change";
  static constexpr Stage kStage = Stage::gap;
  static constexpr ParamSpec kSpecs[] = {
      {"gap_deg", 0, 90, false, false, kNaN, "gap at t = 0"},
      {"step_time_s", 0, 1e7, false, false, 0.0, "time of a step change of the gap"},
      {"step_deg", -90, 90, false, false, 0.0, "size of the step change"},
      {"drift_deg_per_s", -10, 10, false, false, 0.0, "linear drift of the gap"},
  };
  using ScalarEffect::ScalarEffect;

  void settle(std::span<double>, Signals& s) const override { apply(s); }
  void step(std::span<double>, Signals& s, double, Rng&) const noexcept override { apply(s); }

 private:
  void apply(Signals& s) const noexcept {
    const double gap_deg = value(0) + (s.t_s >= value(1) ? value(2) : 0.0) + value(3) * s.t_s;
    s.gap_rad = units::deg_to_rad(std::max(gap_deg, 0.0));
  }
};

HIL_REGISTER_EFFECT(BacklashChange, "gap size other than the model's, with a step and/or a drift")

}  // namespace hil::plant
