// Candidate effect: the transducer (or its tubing) responds with a first-order lag.
#include <cmath>

#include "hil/plant/registry.hpp"

namespace hil::plant {

class SensorLag final : public ScalarEffect<SensorLag> {
 public:
  static constexpr std::string_view kKind = "sensor_lag";
  static constexpr Stage kStage = Stage::sensor;
  static constexpr ParamSpec kSpecs[] = {
      {"time_constant_s", 0, 10, false, false, kNaN, "first-order lag of the pressure reading"},
  };
  using ScalarEffect::ScalarEffect;

  std::size_t state_size() const noexcept override { return 1; }
  void settle(std::span<double> x, Signals& s) const override { x[0] = s.p_meas_pa; }
  void step(std::span<double> x, Signals& s, double dt_s, Rng&) const noexcept override {
    const double keep = value(0) > 0 ? std::exp(-dt_s / value(0)) : 0.0;
    x[0] = s.p_meas_pa + (x[0] - s.p_meas_pa) * keep;
    s.p_meas_pa = x[0];
  }
};

HIL_REGISTER_EFFECT(SensorLag, "first-order lag on the pressure reading")

}  // namespace hil::plant
