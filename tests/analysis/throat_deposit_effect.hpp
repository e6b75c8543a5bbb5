// The user-written effect of analysis/README.md's worked example: slag deposits narrow the
// throat. Registered by including this header in one source file of a test program.
#pragma once

#include "hil/plant/registry.hpp"

namespace hil::plant {

// Slag deposits narrow the throat: the area is (1 - blockage) times what the valve angle gives.
class ThroatDeposit final : public ScalarEffect<ThroatDeposit> {
 public:
  static constexpr std::string_view kKind = "throat_deposit";
  static constexpr Stage kStage = Stage::throat_modifier;
  static constexpr ParamSpec kSpecs[] = {
      {"blockage", 0, 0.9, false, false, 0.0, "fraction of the throat area blocked by deposits"},
  };
  using ScalarEffect::ScalarEffect;
  void settle(std::span<double>, Signals& s) const override { apply(s); }
  void step(std::span<double>, Signals& s, double, Rng&) const noexcept override { apply(s); }

 private:
  void apply(Signals& s) const noexcept { s.throat_area_m2 *= 1.0 - value(0); }
};

HIL_REGISTER_EFFECT(ThroatDeposit, "slag deposits narrow the throat by a fixed fraction")

}  // namespace hil::plant
