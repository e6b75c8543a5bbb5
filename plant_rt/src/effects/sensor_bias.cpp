// Candidate effect: the transducer's offset and gain error: p_meas = gain * p + offset.
#include "hil/plant/registry.hpp"
#include "hil/units.hpp"

namespace hil::plant {

class SensorBias final : public ScalarEffect<SensorBias> {
 public:
  static constexpr std::string_view kKind = "sensor_bias";
  static constexpr Stage kStage = Stage::sensor_modifier;
  static constexpr ParamSpec kSpecs[] = {
      {"offset_kpa", -1e4, 1e4, false, false, 0.0, "offset of the pressure reading"},
      {"gain", 0.1, 10, false, false, 1.0, "gain of the pressure reading"},
  };
  using ScalarEffect::ScalarEffect;

  void settle(std::span<double>, Signals& s) const override { apply(s); }
  void step(std::span<double>, Signals& s, double, Rng&) const noexcept override { apply(s); }

 private:
  void apply(Signals& s) const noexcept { s.p_meas_pa = value(1) * s.p_meas_pa + value(0) * units::kPaPerKpa; }
};

HIL_REGISTER_EFFECT(SensorBias, "offset and gain of the pressure reading")

}  // namespace hil::plant
