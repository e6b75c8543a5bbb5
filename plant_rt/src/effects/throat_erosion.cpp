// Candidate effect: hot gas erodes the throat, so its area grows during the run, linearly in
// time: by a fixed area per second (additive: A + r t), or in proportion to the area the valve
// opens (proportional: A (1 + e t), erosion along the whole wetted edge). Both default to 0.
#include <cmath>

#include "hil/plant/fit_prior.hpp"
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

  // How diagnose finds it (fit_prior.hpp): additive (A + r t) and proportional (A (1 + e t)) have
  // as many parameters, so the criterion picks the form that fits; they differ where the valve
  // opening changes.
  static FitPrior fit_prior(const FitEvidence& ev) {
    const double r = ev.model_value("throat_erosion", "rate_mm2_per_s");
    const double e = ev.model_value("throat_erosion", "proportional_rate_per_s");
    FitPrior p;
    p.description =
        "the throat area grows (or shrinks, deposits) linearly over the run, by a fixed area per second or "
        "in proportion to the area";
    p.params = {{.key = "rate_mm2_per_s", .neutral = 0, .lo = -5, .hi = 5, .scale = 0.05, .starts = {std::isfinite(r) ? r : 0.0}},
                {.key = "proportional_rate_per_s",
                 .neutral = 0,
                 .lo = -0.05,
                 .hi = 0.05,
                 .scale = 5e-4,
                 .starts = {std::isfinite(e) ? e : 0.0}}};
    p.variants = {{"rate", {"rate_mm2_per_s"}}, {"proportional", {"proportional_rate_per_s"}}};
    return p;
  }

  void settle(std::span<double>, Signals& s) const override { apply(s); }
  void step(std::span<double>, Signals& s, double, Rng&) const noexcept override { apply(s); }

 private:
  void apply(Signals& s) const noexcept {
    s.throat_area_m2 = std::max(s.throat_area_m2 * (1 + value(1) * s.t_s) + value(0) * units::kM2PerMm2 * s.t_s, 1e-9);
  }
};

HIL_REGISTER_EFFECT(ThroatErosion, "throat area growing during the run")
HIL_REGISTER_FIT_PRIOR(ThroatErosion)

}  // namespace hil::plant
