// Candidate effect: the transducer's offset and gain error: p_meas = gain * p + offset.
#include <cmath>

#include "hil/plant/fit_prior.hpp"
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

  // How diagnose finds it (fit_prior.hpp): an offset, a gain, or both.
  static FitPrior fit_prior(const FitEvidence& ev) {
    const double o = ev.model_value("sensor_bias", "offset_kpa"), g = ev.model_value("sensor_bias", "gain");
    FitPrior p;
    p.description = "the pressure reading has an offset and/or a gain error";
    p.params = {{.key = "offset_kpa", .lo = -500, .hi = 500, .scale = 5, .starts = {std::isfinite(o) ? o : 0.0}},
                {.key = "gain", .lo = 0.5, .hi = 2, .scale = 0.01, .starts = {std::isfinite(g) ? g : 1.0}}};
    p.variants = {{"offset", {"offset_kpa"}}, {"gain", {"gain"}}, {"offset and gain", {"offset_kpa", "gain"}}};
    return p;
  }

  void settle(std::span<double>, Signals& s) const override { apply(s); }
  void step(std::span<double>, Signals& s, double, Rng&) const noexcept override { apply(s); }

 private:
  void apply(Signals& s) const noexcept { s.p_meas_pa = value(1) * s.p_meas_pa + value(0) * units::kPaPerKpa; }
};

HIL_REGISTER_EFFECT(SensorBias, "offset and gain of the pressure reading")
HIL_REGISTER_FIT_PRIOR(SensorBias)

}  // namespace hil::plant
