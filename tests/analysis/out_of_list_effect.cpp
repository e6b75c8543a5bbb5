// An effect outside the candidate list, for the "unexplained" test: a combustion-driven pressure
// oscillation in the chamber (a limit cycle the lumped model cannot have). Its parameters have no
// defaults, so diagnose does not pick it up as a user candidate: it stays truly unknown.
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

}  // namespace hil::plant
