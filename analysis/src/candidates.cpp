#include "hil/analysis/candidates.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>

#include "hil/config.hpp"
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

double gap_of(const plant::Plant& base) {
  const double g = value_of(base, "backlash_change", "gap_deg");
  return std::isfinite(g) ? g : value_of(base, "backlash", "gap_deg");
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

Candidate backlash_change(const plant::Plant& base) {
  const double gap = gap_of(base);
  Candidate c;
  c.name = "backlash_change";
  c.description = "the gap differs from the model's: constant, drifting, or stepping once at an unknown time";
  c.attach = [gap](const plant::Plant& p) { return add_block(p, "backlash_change", "gap_deg: " + num(gap)); };
  FreeParam g{"backlash_change", "gap_deg", 0.0, 10.0, 0.2, {gap, 0.5 * gap, 2 * gap}};
  const FreeParam drift{"backlash_change", "drift_deg_per_s", -0.5, 0.5, 0.005, {0.0}};
  FreeParam size{"backlash_change", "step_deg", -5.0, 5.0, 0.2, {0.5, -0.5}};
  // Wear and assembly change a gear's play by a fraction of it, not by multiples.
  g.credible_lo = 0, g.credible_hi = 3 * gap, g.credible_why = "three times the model's gap of " + num(gap) + " deg";
  size.credible_lo = -2 * gap, size.credible_hi = 2 * gap, size.credible_why = "twice the model's gap of " + num(gap) + " deg";
  FreeParam when{"backlash_change", "step_time_s", 0.0, 1e7, 1.0, {}, true, step_times};
  c.variants = {{"constant gap", {g}}, {"drifting gap", {g, drift}}, {"gap step", {g, size, when}}};
  return c;
}

Candidate valve_offset(const plant::Plant& base) {
  const double v = value_of(base, "valve_offset", "offset_deg");
  Candidate c;
  c.name = "valve_offset";
  c.description = "the valve's zero differs from the motor's, so the throat sees a shifted angle";
  c.attach = [](const plant::Plant& p) { return add_block(p, "valve_offset", "offset_deg: 0"); };
  c.variants = {{"offset", {{"valve_offset", "offset_deg", -10.0, 10.0, 0.2, {std::isfinite(v) ? v : 0.0, -1.0, 1.0}}}}};
  return c;
}

Candidate throat_erosion(const plant::Plant& base) {
  const double v = value_of(base, "throat_erosion", "rate_mm2_per_s");
  Candidate c;
  c.name = "throat_erosion";
  const double e = value_of(base, "throat_erosion", "proportional_rate_per_s");
  c.description =
      "the throat area grows (or shrinks, deposits) linearly over the run, by a fixed area per second or "
      "in proportion to the area";
  c.attach = [](const plant::Plant& p) {
    return add_block(p, "throat_erosion", "{rate_mm2_per_s: 0, proportional_rate_per_s: 0}");
  };
  // Additive (A + r t) and proportional (A (1 + e t)): the same count of parameters, so the
  // criterion picks the form that fits; they differ where the valve opening changes.
  c.variants = {
      {"rate", {{"throat_erosion", "rate_mm2_per_s", -5.0, 5.0, 0.05, {std::isfinite(v) ? v : 0.0}}}},
      {"proportional", {{"throat_erosion", "proportional_rate_per_s", -0.05, 0.05, 5e-4, {std::isfinite(e) ? e : 0.0}}}}};
  return c;
}

Candidate sensor_lag(const plant::Plant& base) {
  const double v = value_of(base, "sensor_lag", "time_constant_s");
  Candidate c;
  c.name = "sensor_lag";
  c.description = "the pressure transducer (or its tubing) responds with a first-order lag";
  c.attach = [](const plant::Plant& p) { return add_block(p, "sensor_lag", "time_constant_s: 0"); };
  std::vector<double> starts = {0.003, 0.01, 0.03, 0.1};
  if (std::isfinite(v)) starts.insert(starts.begin(), v);
  FreeParam tau{"sensor_lag", "time_constant_s", 0.0, 0.5, 0.005, starts};
  tau.sample_step = true;
  c.variants = {{"time constant", {tau}}};
  return c;
}

Candidate transport_delay(const plant::Plant& base) {
  const double v = value_of(base, "transport_delay", "delay_s");
  Candidate c;
  c.name = "transport_delay";
  c.description = "a pure delay between the command and the drive acting on it";
  c.command_side = true;
  c.attach = [](const plant::Plant& p) { return add_block(p, "transport_delay", "delay_s: 0"); };
  std::vector<double> starts = {0.005, 0.02, 0.05, 0.1};
  if (std::isfinite(v)) starts.insert(starts.begin(), v);
  FreeParam delay{"transport_delay", "delay_s", 0.0, 0.5, 0.005, starts};
  delay.sample_step = true;
  c.variants = {{"delay", {delay}}};
  return c;
}

Candidate sensor_bias(const plant::Plant& base) {
  const double o = value_of(base, "sensor_bias", "offset_kpa"), g = value_of(base, "sensor_bias", "gain");
  Candidate c;
  c.name = "sensor_bias";
  c.description = "the pressure reading has an offset and/or a gain error";
  c.attach = [](const plant::Plant& p) { return add_block(p, "sensor_bias", ""); };
  const FreeParam off{"sensor_bias", "offset_kpa", -500.0, 500.0, 5.0, {std::isfinite(o) ? o : 0.0}};
  const FreeParam gain{"sensor_bias", "gain", 0.5, 2.0, 0.01, {std::isfinite(g) ? g : 1.0}};
  c.variants = {{"offset", {off}}, {"gain", {gain}}, {"offset and gain", {off, gain}}};
  return c;
}

Candidate motor_dynamics(const plant::Plant& base) {
  const double tau = value_of(base, "motor_servo", "time_constant_s");
  const double rate = value_of(base, "motor_servo", "rate_limit_deg_s");
  Candidate c;
  c.name = "motor_dynamics";
  c.description = "the servo's lag or rate limit differs from the model's (refits motor_servo)";
  c.command_side = true;
  c.attach = [](const plant::Plant& p) { return p; };
  FreeParam t{"motor_servo", "time_constant_s", 1e-4, 0.5, 0.002, {tau, 3 * tau, 8 * tau}};
  t.sample_step = true;
  const FreeParam r{"motor_servo", "rate_limit_deg_s", 1.0, 1000.0, 1.0, {rate, 0.5 * rate, 0.25 * rate}};
  c.variants = {{"lag", {t}}, {"rate limit", {r}}, {"lag and rate limit", {t, r}}};
  return c;
}

Candidate burn_rate(const plant::Plant& base) {
  const double a = value_of(base, "gas_generator", "burn_rate_mm_s_at_1mpa");
  const double n = value_of(base, "gas_generator", "pressure_exponent");
  Candidate c;
  c.name = "burn_rate";
  c.description = "the propellant's burn-rate coefficient a or exponent n differs (refits gas_generator)";
  c.attach = [](const plant::Plant& p) { return p; };
  const FreeParam pa{"gas_generator", "burn_rate_mm_s_at_1mpa", 0.5 * a, 2.0 * a, 0.01 * a, {a}};
  const FreeParam pn{"gas_generator", "pressure_exponent", 0.05, 0.9, 0.005, {n}};
  c.variants = {{"coefficient a", {pa}}, {"exponent n", {pn}}, {"a and n", {pa, pn}}};
  return c;
}

const std::vector<std::string> kBuiltin = {"backlash_change", "valve_offset", "throat_erosion", "sensor_lag",
                                           "transport_delay", "sensor_bias",  "motor_dynamics", "burn_rate"};

// A registered effect the model lacks, whose defaults all exist: a candidate by itself.
bool user_candidate(const plant::Plant& base, const std::string& kind, const plant::EffectInfo& info) {
  if (base.find(kind)) return false;
  if (std::find(kBuiltin.begin(), kBuiltin.end(), kind) != kBuiltin.end()) return false;
  // Any stage: at the motor, transmission, throat and chamber stages the effect runs after the
  // model's own (attach appends it; plant.hpp), modifying its signal (a stiction after the
  // backlash). Not sensor noise: random noise has no deterministic replay to fit, and the noise
  // model measures it from the data.
  if (info.stage == plant::Stage::sensor_noise) return false;
  try {
    const auto e = info.from_yaml(cfg::Node::load_string("{}", kind));
    return !e->specs().empty();
  } catch (const std::exception&) {
    return false;  // a required parameter: no neutral default to start from
  }
}

Candidate from_registry(const std::string& kind, const plant::EffectInfo& info) {
  const auto neutral = info.from_yaml(cfg::Node::load_string("{}", kind));
  Candidate c;
  c.name = kind;
  c.description = std::string(info.doc) + " (user effect)";
  c.command_side = info.stage == plant::Stage::command;
  c.attach = [neutral](const plant::Plant& p) { return p.with(neutral); };
  Variant v{"all parameters", {}};
  const auto params = neutral->params();
  const auto specs = neutral->specs();
  for (std::size_t i = 0; i < specs.size(); ++i) {
    const auto& s = specs[i];
    const double width = s.hi - s.lo;
    double lo = s.lo, hi = s.hi;
    // Open bounds: stay a hair inside; huge ranges: keep the fit near the default.
    const double pad = std::isfinite(width) && width > 0 ? 1e-9 * width : 1e-9;
    if (s.lo_open) lo += pad;
    if (s.hi_open) hi -= pad;
    const double start = params[i].value;
    const double scale = start != 0 ? std::abs(start) * 0.1 : (width < 1e3 ? width / 100 : 1.0);
    // "Absent" at an end of a finite range (a breakaway of 0): the cost can be flat or rugged
    // there (a stick-slip's has a sharp optimum: LM from 0 ended at 94.99 %, from the best of 1, 3,
    // 10, 30 % of the range at 94.27 %, on a file whose truth reaches 98.86 %), so start points
    // spread over the range inwards are tried first: for a lone parameter a log grid of 120 from
    // 0.2 % of the range (6 % apart; fit.cpp tries every one), else 3 and 30 % (their product is
    // tried).
    std::vector<double> starts = {start};
    const bool at_end = start == s.lo || start == s.hi;
    if (at_end && std::isfinite(width) && width > 0 && width < 1e6) {
      const double inward = start == s.lo ? 1.0 : -1.0;
      std::vector<double> fractions = {0.03, 0.3};
      if (specs.size() == 1) {
        fractions.clear();
        for (int k = 0; k < 120; ++k) fractions.push_back(0.002 * std::pow(500.0, k / 119.0));
      }
      for (double f : fractions) starts.push_back(std::clamp(start + inward * f * width, lo, hi));
    }
    v.params.push_back({kind, std::string(s.key), lo, hi, scale, starts});
  }
  c.variants = {v};
  return c;
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

std::vector<Candidate> candidates_for(const plant::Plant& base, const std::vector<std::string>& only) {
  std::vector<Candidate> all = {backlash_change(base), valve_offset(base), throat_erosion(base), sensor_lag(base),
                                transport_delay(base), sensor_bias(base),  motor_dynamics(base), burn_rate(base)};
  for (const auto& kind : plant::effect_names()) {
    const plant::EffectInfo* info = plant::find_effect(kind);
    if (info && user_candidate(base, kind, *info)) all.push_back(from_registry(kind, *info));
  }
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
