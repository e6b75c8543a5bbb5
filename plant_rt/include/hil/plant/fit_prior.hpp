// How the workbench looks for an effect (`hilbench diagnose`, analysis/README.md "Adding an
// effect"): declared by the effect itself, beside its parameter specs, in its own file, so that an
// effect and how to find it are one file. Per parameter: fixed or free, the fit range, start
// points or a grid; and the forms (variants) the search tries, each a set of free parameters.
// Plain data made by a function of what the model and the file show (a gap's starts from the
// model's gap, a rate limit's from what the file's command asks of the drive). plant_rt never reads
// it: the simulation and the real-time loop are untouched; analysis/src/candidates.cpp turns it
// into a candidate. An effect without one is still a candidate when its parameters' defaults mean
// "absent" (all free, started from those defaults).
#pragma once

#include <cstdio>
#include <functional>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "hil/registry.hpp"

namespace hil::plant {

// What a prior may look at.
struct FitEvidence {
  // A parameter of the model the effect joins (NaN: the model has no such block or key).
  std::function<double(std::string_view kind, std::string_view key)> model_value;
  // What the file's command asks of the drive: the 95th percentile of |d theta_cmd / dt| [deg/s]
  // over the rows where it moves (NaN: unknown). A rate limit above it never binds on this file.
  double command_rate_deg_s = std::numeric_limits<double>::quiet_NaN();
};

// How a parameter is searched. A grid parameter is not fitted by LM but searched on its values.
enum class FitGrid {
  none,
  run_time,  // an event time: every 10 ms of the run (or every coarse row), zoomed in
  range,     // grid_points values spread evenly over [lo, hi], zoomed in
};

struct FitParam {
  std::string key;                                            // the parameter's key in the effect's specs
  double fixed = std::numeric_limits<double>::quiet_NaN();    // finite: held at this value, never fitted
  double neutral = std::numeric_limits<double>::quiet_NaN();  // "no change" when the block is added (NaN: default)
  double lo = std::numeric_limits<double>::quiet_NaN();       // fit range (NaN: the spec's)
  double hi = std::numeric_limits<double>::quiet_NaN();
  double scale = std::numeric_limits<double>::quiet_NaN();  // typical size: LM scaling (NaN: from the range)
  std::vector<double> starts = {};                          // tried before LM, the best starts it (empty: the neutral value, and
                                                            // points spread inwards when that is an end of the range)
  FitGrid grid = FitGrid::none;
  int grid_points = 0;       // FitGrid::range
  bool sample_step = false;  // a time constant or delay: finite differences of at least one sample period
  // What the nominal plant makes credible (NaN: anything in range) and why: outside it the fitted
  // value is flagged, not refused.
  double credible_lo = std::numeric_limits<double>::quiet_NaN();
  double credible_hi = std::numeric_limits<double>::quiet_NaN();
  std::string credible_why = {};
};

struct FitVariant {
  std::string name;               // "constant gap", "drift and step", ...
  std::vector<std::string> free;  // the keys this form fits; the others stay neutral (or fixed)
  // A richer form, never tried on its own: only in place of an accepted form of this effect whose
  // keys it holds, and kept only when its extra parameters earn their place against that form as a
  // new effect must (a drift and a step together: tried from the start, it explained a temporary
  // throat blockage; the effect must first be found in a simpler form).
  bool extends = false;
};

struct FitPrior {
  std::string candidate;    // the name diagnose reports (empty: the effect's kind)
  std::string description;  // one sentence (empty: the registry's doc)
  // Refits the model's own block (a servo's lag, a burn rate) rather than adding a new one.
  bool refit = false;
  // Acts before the motor angle: invisible when the encoder is replayed (the command stage always is).
  bool command_side = false;
  std::vector<FitParam> params;      // the parameters the search may touch (others stay at their default)
  std::vector<FitVariant> variants;  // empty: one form, every non-fixed parameter free
};

// A number as a prior's words give it (credible_why): up to 10 significant digits.
inline std::string fit_num(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.10g", v);
  return b;
}

using FitPriorFn = FitPrior (*)(const FitEvidence&);

struct FitPriorInfo {
  std::string_view kind;
  FitPriorFn make;
};

inline bool register_fit_prior(std::string_view kind, FitPriorFn make) {
  Registry<FitPriorInfo>::add(kind, {kind, make});
  return true;
}
inline const FitPriorInfo* find_fit_prior(std::string_view kind) { return Registry<FitPriorInfo>::find(kind); }

}  // namespace hil::plant

// Beside HIL_REGISTER_EFFECT(Class, ...): Class has `static FitPrior fit_prior(const FitEvidence&)`.
#define HIL_REGISTER_FIT_PRIOR(Class)                                                                                \
  namespace {                                                                                                        \
  [[maybe_unused]] const bool fit_prior_##Class = ::hil::plant::register_fit_prior(Class::kKind, &Class::fit_prior); \
  }
