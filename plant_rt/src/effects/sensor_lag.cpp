// Candidate effect: the transducer (or its tubing) responds with a first-order lag.
#include <cmath>

#include "hil/plant/fit_prior.hpp"
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

  // How diagnose finds it (fit_prior.hpp): the cost is flat at 0, so LM starts from the best of a
  // few time constants.
  static FitPrior fit_prior(const FitEvidence& ev) {
    const double v = ev.model_value("sensor_lag", "time_constant_s");
    std::vector<double> starts = {0.003, 0.01, 0.03, 0.1};
    if (std::isfinite(v)) starts.insert(starts.begin(), v);
    FitPrior p;
    p.description = "the pressure transducer (or its tubing) responds with a first-order lag";
    p.params = {
        {.key = "time_constant_s", .neutral = 0, .lo = 0, .hi = 0.5, .scale = 0.005, .starts = starts, .sample_step = true}};
    p.variants = {{"time constant", {"time_constant_s"}}};
    return p;
  }

  std::size_t state_size() const noexcept override { return 1; }
  void settle(std::span<double> x, Signals& s) const override { x[0] = s.p_meas_pa; }
  void step(std::span<double> x, Signals& s, double dt_s, Rng&) const noexcept override {
    const double keep = value(0) > 0 ? std::exp(-dt_s / value(0)) : 0.0;
    x[0] = s.p_meas_pa + (x[0] - s.p_meas_pa) * keep;
    s.p_meas_pa = x[0];
  }
};

HIL_REGISTER_EFFECT(SensorLag, "first-order lag on the pressure reading")
HIL_REGISTER_FIT_PRIOR(SensorLag)

}  // namespace hil::plant
