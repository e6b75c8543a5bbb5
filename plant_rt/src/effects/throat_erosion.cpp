// Candidate effect: hot gas erodes the throat, so its area grows during the run, linearly in
// time: by a fixed area per second (additive: A + r t), or in proportion to the area the valve
// opens (proportional: A (1 + e t), erosion along the whole wetted edge). Both default to 0.
#include "hil/plant/registry.hpp"
#include "hil/units.hpp"

namespace hil::plant {

class ThroatErosion final : public ScalarEffect<ThroatErosion> {
 public:
  static constexpr std::string_view kKind = "throat_erosion";
  static constexpr Stage kStage = Stage::throat_modifier;
  static constexpr ParamSpec kSpecs[] = {
      {"rate_mm2_per_s", -100, 100, false, false, 0.0, "growth rate of the throat area (additive)"},
      {"proportional_rate_per_s", -1, 1, false, false, 0.0, "relative growth rate of the throat area: A (1 + e t)"},
  };
  using ScalarEffect::ScalarEffect;

  void settle(std::span<double>, Signals& s) const override { apply(s); }
  void step(std::span<double>, Signals& s, double, Rng&) const noexcept override { apply(s); }

 private:
  void apply(Signals& s) const noexcept {
    s.throat_area_m2 = std::max(s.throat_area_m2 * (1 + value(1) * s.t_s) + value(0) * units::kM2PerMm2 * s.t_s, 1e-9);
  }
};

HIL_REGISTER_EFFECT(ThroatErosion, "throat area growing during the run")

}  // namespace hil::plant
