// The pressure transducer's white noise, added last so no downstream stage filters it.
#include "hil/plant/registry.hpp"
#include "hil/units.hpp"

namespace hil::plant {

class PressureSensor final : public ScalarEffect<PressureSensor> {
 public:
  static constexpr std::string_view kKind = "pressure_sensor";
  static constexpr Stage kStage = Stage::sensor_noise;
  static constexpr ParamSpec kSpecs[] = {
      {"noise_rms_kpa", 0, 1e4, false, false, 0.0, "white noise of the pressure reading, RMS"},
  };
  using ScalarEffect::ScalarEffect;

  void settle(std::span<double>, Signals&) const override {}  // settle is noise-free
  void step(std::span<double>, Signals& s, double, Rng& rng) const noexcept override {
    if (value(0) > 0) s.p_meas_pa += value(0) * units::kPaPerKpa * rng.gaussian();
  }
};

HIL_REGISTER_EFFECT(PressureSensor, "pressure transducer white noise")

}  // namespace hil::plant
