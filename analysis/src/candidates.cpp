#include "hil/analysis/candidates.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>

#include "hil/config.hpp"
#include "hil/plant/fit_prior.hpp"
#include "hil/plant/registry.hpp"
#include "hil/units.hpp"

namespace hil::analysis {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Adds a block of `kind` with the given parameter values (all others at their defaults).
plant::Plant add_block(const plant::Plant& base, const std::string& kind, const std::string& yaml_params) {
  if (base.find(kind)) return base;
  const plant::EffectInfo* info = plant::find_effect(kind);
  if (info == nullptr) throw std::logic_error("candidate effect '" + kind + "' is not registered");
  const auto node = cfg::Node::load_string(yaml_params.empty() ? "{}" : yaml_params, kind + " (candidate)");
  return base.with(info->from_yaml(node));
}

std::string num(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.10g", v);
  return b;
}

// Candidate step times: a uniform grid over the run (model clock), 10 ms apart or one coarse row.
// Not only the reversals matter: a gap that grows while a flank pushes stops the valve until the
// motor has taken up the extra play, so the cost is roughly V-shaped around the true time, with
// plateaus where the drive holds; the zoom search in diagnose finds its bottom.
std::vector<double> step_times(const ReplayData& data) {
  // Every row's time (at least 10 ms apart) of every file, on the runs' joint clock (replay.hpp,
  // segment_model): with several files the step belongs to one of them, and it may also have
  // happened between two runs (the later file's offset: in force from its first row).
  std::vector<double> out;
  for (std::size_t i = 0; i < data.segments.size(); ++i) {
    const std::size_t rows = data.segment_end(i) - data.segment_begin(i);
    if (rows < 4) continue;
    const double span = data.span_s(i), offset = data.segments[i].clock_offset_s;
    const double spacing = std::max(0.01, span / static_cast<double>(rows - 1));
    if (i > 0) out.push_back(offset);
    for (double t = spacing; t < span; t += spacing) out.push_back(offset + t);
  }
  return out;
}

// The built-in candidates, in the order diagnose has always ranked and reported them; each
// declares its fit prior in its effect's own file (plant_rt/src/effects/).
const std::vector<std::string> kBuiltin = {"backlash_change", "valve_offset", "throat_erosion", "sensor_lag",
                                           "transport_delay", "sensor_bias",  "motor_dynamics", "burn_rate"};

// The prior of an effect that declares none: every parameter free, started from its default
// ("absent"); nullopt when it cannot be a candidate.
std::optional<plant::FitPrior> default_prior(const std::string& kind, const plant::EffectInfo& info) {
  // Not sensor noise: random noise has no deterministic replay to fit, and the noise model
  // measures it from the data.
  if (info.stage == plant::Stage::sensor_noise) return std::nullopt;
  try {
    const auto e = info.from_yaml(cfg::Node::load_string("{}", kind));
    if (e->specs().empty()) return std::nullopt;
    plant::FitPrior p;
    for (const auto& s : e->specs()) p.params.push_back({.key = std::string(s.key)});
    return p;
  } catch (const std::exception&) {
    return std::nullopt;  // a required parameter: no neutral default to start from
  }
}

// A prior's parameter as the fitter's FreeParam, inside the effect's spec `s`; `neutral` its value
// when the block is attached, `lone` when it is its form's only free parameter.
FreeParam free_param(const std::string& kind, const plant::FitParam& fp, const plant::ParamSpec& s, double neutral, bool lone) {
  const double width = s.hi - s.lo;
  double lo = s.lo, hi = s.hi;
  // Open bounds: stay a hair inside.
  const double pad = std::isfinite(width) && width > 0 ? 1e-9 * width : 1e-9;
  if (s.lo_open) lo += pad;
  if (s.hi_open) hi -= pad;
  if (std::isfinite(fp.lo)) lo = fp.lo;
  if (std::isfinite(fp.hi)) hi = fp.hi;
  // Huge ranges: keep the steps near the default.
  const double scale = std::isfinite(fp.scale) ? fp.scale
                       : neutral != 0          ? std::abs(neutral) * 0.1
                                               : (width < 1e3 ? width / 100 : 1.0);
  std::vector<double> starts = fp.starts;
  if (starts.empty() && fp.grid == plant::FitGrid::none) {
    // "Absent" at an end of a finite range (a breakaway of 0): the cost can be flat or rugged
    // there (a stick-slip's has a sharp optimum: LM from 0 ended at 94.99 %, from the best of 1, 3,
    // 10, 30 % of the range at 94.27 %, on a file whose truth reaches 98.86 %), so start points
    // spread over the range inwards are tried first: for a lone parameter a log grid of 120 from
    // 0.2 % of the range (6 % apart; fit.cpp tries every one), else 3 and 30 % (their product is
    // tried).
    starts = {neutral};
    const double w = hi - lo;
    const bool at_end = neutral == s.lo || neutral == s.hi;
    if (at_end && std::isfinite(w) && w > 0 && w < 1e6) {
      const double inward = neutral == s.lo ? 1.0 : -1.0;
      std::vector<double> fractions = {0.03, 0.3};
      if (lone) {
        fractions.clear();
        for (int k = 0; k < 120; ++k) fractions.push_back(0.002 * std::pow(500.0, k / 119.0));
      }
      for (double f : fractions) starts.push_back(std::clamp(neutral + inward * f * width, lo, hi));
    }
  }
  FreeParam out{kind, fp.key, lo, hi, scale, starts};
  if (fp.grid == plant::FitGrid::run_time) {
    out.grid = true, out.grid_values = step_times;
  } else if (fp.grid == plant::FitGrid::range) {
    const int n = std::max(2, fp.grid_points);
    out.grid = true;
    out.grid_values = [lo, hi, n](const ReplayData&) {
      std::vector<double> v;
      for (int i = 0; i < n; ++i) v.push_back(lo + (hi - lo) * i / (n - 1));
      return v;
    };
  }
  out.sample_step = fp.sample_step;
  out.credible_lo = fp.credible_lo, out.credible_hi = fp.credible_hi, out.credible_why = fp.credible_why;
  return out;
}

// An effect and its fit prior as a candidate; nullopt when the prior leaves nothing to fit or
// names a key the effect does not have (a mistake in the effect's file: said, not hidden).
Candidate from_prior(const plant::Plant& base, const std::string& kind, const plant::EffectInfo& info,
                     const plant::FitPrior& prior) {
  Candidate c;
  c.name = prior.candidate.empty() ? kind : prior.candidate;
  c.description = prior.description.empty() ? std::string(info.doc) + " (user effect)" : prior.description;
  c.command_side = prior.command_side || info.stage == plant::Stage::command;
  // The block as attached: the model's own when it has one (refitted), else added at the prior's
  // neutral values; fixed parameters at their values either way.
  std::string yaml;
  std::vector<FreeParam> held;
  std::vector<double> held_values;
  for (const auto& fp : prior.params) {
    const double v = std::isfinite(fp.fixed) ? fp.fixed : fp.neutral;
    if (std::isfinite(v)) yaml += (yaml.empty() ? "" : ", ") + fp.key + ": " + num(v);
    if (std::isfinite(fp.fixed)) held.push_back({kind, fp.key}), held_values.push_back(fp.fixed);
  }
  const bool refit = prior.refit;
  c.attach = [kind, yaml, refit, held, held_values](const plant::Plant& p) {
    plant::Plant out = refit || p.find(kind) ? p : add_block(p, kind, "{" + yaml + "}");
    return held.empty() ? out : with_values(out, held, held_values);
  };
  const plant::Plant attached = c.attach(base);
  const auto specs = attached.find(kind)->specs();
  auto spec_of = [&](const std::string& key) -> const plant::ParamSpec& {
    for (const auto& s : specs)
      if (s.key == key) return s;
    throw std::logic_error("the fit prior of effect '" + kind + "' names '" + key + "', which is not one of its parameters");
  };
  for (const auto& fp : prior.params) spec_of(fp.key);
  auto forms = prior.variants;
  if (forms.empty()) {
    plant::FitVariant all{"all parameters", {}};
    for (const auto& fp : prior.params)
      if (!std::isfinite(fp.fixed)) all.free.push_back(fp.key);
    forms.push_back(all);
  }
  for (const auto& f : forms) {
    Variant v{f.name, {}, f.extends};
    for (const auto& key : f.free) {
      const auto it =
          std::find_if(prior.params.begin(), prior.params.end(), [&](const plant::FitParam& fp) { return fp.key == key; });
      if (it == prior.params.end() || std::isfinite(it->fixed))
        throw std::logic_error("the fit prior of effect '" + kind + "': form '" + f.name + "' frees '" + key +
                               "', which is not a free parameter of the prior");
      double neutral = value_of(attached, kind, key);
      if (!std::isfinite(neutral)) neutral = 0;
      v.params.push_back(free_param(kind, *it, spec_of(key), neutral, f.free.size() == 1));
    }
    if (!v.params.empty()) c.variants.push_back(std::move(v));
  }
  return c;
}

std::size_t builtin_rank(const std::string& name) {
  return static_cast<std::size_t>(std::find(kBuiltin.begin(), kBuiltin.end(), name) - kBuiltin.begin());
}

}  // namespace

std::vector<std::string> builtin_candidate_names() { return kBuiltin; }

double value_of(const plant::Plant& plant, const std::string& effect, const std::string& key) {
  const plant::Effect* e = plant.find(effect);
  if (e == nullptr) return kNaN;
  for (const auto& p : e->params())
    if (p.key == key) return p.value;
  return kNaN;
}

plant::Plant with_values(const plant::Plant& plant, const std::vector<FreeParam>& params, const std::vector<double>& values) {
  std::map<std::string, std::vector<std::pair<std::string, double>>> by_effect;
  for (std::size_t i = 0; i < params.size(); ++i) by_effect[params[i].effect].push_back({params[i].key, values[i]});
  plant::Plant out = plant;
  for (const auto& [kind, kv] : by_effect) {
    const plant::Effect* e = out.find(kind);
    if (e == nullptr) throw std::invalid_argument("the model has no '" + kind + "' block to fit");
    auto current = e->params();
    std::vector<double> v;
    for (auto& p : current) {
      for (const auto& [k, x] : kv)
        if (p.key == k) p.value = x;
      v.push_back(p.value);
    }
    out = out.with(e->with_params(v));
  }
  return out;
}

double command_rate_deg_s(const ReplayData& data) {
  // |d theta_cmd / dt| over 10 ms spans of rows (a row-to-row difference of a jittered or
  // quantised command reads noise), on the rows where the command moves at all.
  std::vector<double> rates;
  for (std::size_t i = 0; i < data.segments.size(); ++i) {
    const std::size_t b = data.segment_begin(i), e = data.segment_end(i);
    for (std::size_t k = b + 1, j = b + 1; k < e; ++k) {  // cmd_held_rad[b] is unused
      while (j < k && data.t_s[k] - data.t_s[j] > 0.01) ++j;
      if (j == k || !(data.t_s[k] - data.t_s[j] > 0)) continue;
      const double r = std::abs(data.cmd_held_rad[k] - data.cmd_held_rad[j]) / (data.t_s[k] - data.t_s[j]);
      if (r > 0) rates.push_back(units::rad_to_deg(r));
    }
  }
  if (rates.size() < 10) return kNaN;
  auto at = rates.begin() + static_cast<std::ptrdiff_t>(0.95 * static_cast<double>(rates.size() - 1));
  std::nth_element(rates.begin(), at, rates.end());
  return *at;
}

std::vector<Candidate> candidates_for(const plant::Plant& base, const std::vector<std::string>& only, const ReplayData* data) {
  plant::FitEvidence ev;
  ev.model_value = [&base](std::string_view kind, std::string_view key) {
    return value_of(base, std::string(kind), std::string(key));
  };
  if (data) ev.command_rate_deg_s = command_rate_deg_s(*data);
  std::vector<Candidate> all;
  for (const auto& kind : plant::effect_names()) {
    const plant::EffectInfo* info = plant::find_effect(kind);
    if (info == nullptr) continue;
    std::optional<plant::FitPrior> prior;
    if (const plant::FitPriorInfo* declared = plant::find_fit_prior(kind)) {
      prior = declared->make(ev);  // declared: tried whether or not the model has the block (refitted)
      if (prior->refit && !base.find(kind)) prior.reset();
    } else if (!base.find(kind)) {
      prior = default_prior(kind, *info);
    }
    if (!prior) continue;
    Candidate c = from_prior(base, kind, *info, *prior);
    if (!c.variants.empty()) all.push_back(std::move(c));
  }
  // The built-ins first, in their order; then the others by name.
  std::stable_sort(all.begin(), all.end(),
                   [](const Candidate& a, const Candidate& b) { return builtin_rank(a.name) < builtin_rank(b.name); });
  if (only.empty()) return all;
  std::vector<Candidate> out;
  for (const auto& name : only) {
    const auto it = std::find_if(all.begin(), all.end(), [&](const Candidate& c) { return c.name == name; });
    if (it == all.end()) {
      std::string known;
      for (const auto& c : all) known += (known.empty() ? "" : ", ") + c.name;
      throw std::invalid_argument("unknown candidate '" + name + "'; known: " + known);
    }
    out.push_back(*it);
  }
  return out;
}

}  // namespace hil::analysis
