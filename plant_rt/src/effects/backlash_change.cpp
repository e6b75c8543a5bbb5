// Candidate effect: the gap differs from the model's and/or changes during the run:
//   gap(t) = gap_deg + (t >= step_time_s ? step_deg : 0) + drift_deg_per_s * t,  never below 0.
#include <algorithm>
#include <cmath>

#include "hil/plant/fit_prior.hpp"
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

  // How diagnose finds it (fit_prior.hpp): from the model's gap; a constant, drifting or stepping
  // gap, and a drift with a step only as an extension of an accepted form (its extra parameters
  // must earn their place: tried as a first choice, it explained a temporary throat blockage).
  static FitPrior fit_prior(const FitEvidence& ev) {
    double gap = ev.model_value("backlash_change", "gap_deg");
    if (!std::isfinite(gap)) gap = ev.model_value("backlash", "gap_deg");
    const std::string g_text = fit_num(gap);
    FitPrior p;
    p.description = "the gap differs from the model's: constant, drifting, or stepping once at an unknown time";
    // Wear and assembly change a gear's play by a fraction of it, not by multiples.
    p.params = {
        {.key = "gap_deg",
         .neutral = gap,
         .lo = 0,
         .hi = 10,
         .scale = 0.2,
         .starts = {gap, 0.5 * gap, 2 * gap},
         .credible_lo = 0,
         .credible_hi = 3 * gap,
         .credible_why = "three times the model's gap of " + g_text + " deg"},
        {.key = "drift_deg_per_s", .lo = -0.5, .hi = 0.5, .scale = 0.005, .starts = {0.0}},
        {.key = "step_deg",
         .lo = -5,
         .hi = 5,
         .scale = 0.2,
         .starts = {0.5, -0.5},
         .credible_lo = -2 * gap,
         .credible_hi = 2 * gap,
         .credible_why = "twice the model's gap of " + g_text + " deg"},
        {.key = "step_time_s", .lo = 0, .hi = 1e7, .scale = 1, .grid = FitGrid::run_time},
    };
    p.variants = {{"constant gap", {"gap_deg"}},
                  {"drifting gap", {"gap_deg", "drift_deg_per_s"}},
                  {"gap step", {"gap_deg", "step_deg", "step_time_s"}},
                  {"drift and step", {"gap_deg", "drift_deg_per_s", "step_deg", "step_time_s"}, true}};
    return p;
  }

  void settle(std::span<double>, Signals& s) const override { apply(s); }
  void step(std::span<double>, Signals& s, double, Rng&) const noexcept override { apply(s); }

 private:
  void apply(Signals& s) const noexcept {
    const double gap_deg = value(0) + (s.t_s >= value(1) ? value(2) : 0.0) + value(3) * s.t_s;
    s.gap_rad = units::deg_to_rad(std::max(gap_deg, 0.0));
  }
};

HIL_REGISTER_EFFECT(BacklashChange, "gap size other than the model's, with a step and/or a drift")
HIL_REGISTER_FIT_PRIOR(BacklashChange)

}  // namespace hil::plant
