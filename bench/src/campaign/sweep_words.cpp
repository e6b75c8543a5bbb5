#include "sweep_words.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <string_view>
#include <utility>
#include <vector>

#include "hil/ctl/compensator.hpp"
#include "hil/param_spec.hpp"
#include "hil/plant/registry.hpp"

namespace hil::bench {
namespace {

using json = nlohmann::json;

constexpr std::size_t kMaxLabelChars = 80, kMaxUnitChars = 16;

// The keys of a campaign (and its controller block) that no parameter spec describes, in words.
// A path matches when its keys (list indices dropped) end with `keys`; `relative` is the label of
// an axis given relative_to another (an increment): the gap changes' targets are then growths.
struct CampaignKey {
  std::string_view keys, label, relative;
};
constexpr CampaignKey kCampaignKeys[] = {
    {"gap.initial_deg", "initial gap", ""},
    {"gap.changes.step.to_deg", "gap after the step", "gap step"},
    {"gap.changes.step.at_s", "time of the gap step", ""},
    {"gap.changes.drift.to_deg", "gap at the drift's end", "gap growth"},
    {"gap.changes.drift.from_s", "start of the gap drift", ""},
    {"gap.changes.drift.to_s", "end of the gap drift", ""},
    {"sensor_noise_kpa", "sensor noise RMS", ""},
    {"seed", "seed", ""},
    {"duration_s", "campaign duration", ""},
    {"period_ms", "control period", ""},
    {"reference.initial_mpa", "initial reference pressure", ""},
    {"known_gap_deg", "gap known to the controller", ""},
    {"initial_gap_deg", "controller's initial gap estimate", ""},
    {"damping_ratio", "damping ratio", ""},
    {"traverse_boost", "traverse boost", ""},
    {"compensator", "compensator", ""},
    {"observer", "compensator", ""},
    {"compensation", "compensation", ""},
};

// Longest suffix first: "_deg_s" before "_s", "_m2_s2" before "_s2".
constexpr std::pair<std::string_view, std::string_view> kUnitSuffixes[] = {
    {"_mm_s_at_1mpa", "mm/s at 1 MPa"},
    {"_kg_m3", "kg/m³"},
    {"_m2_s2", "m²/s²"},
    {"_deg_s", "deg/s"},
    {"_mm2", "mm²"},
    {"_m_s", "m/s"},
    {"_kpa", "kPa"},
    {"_mpa", "MPa"},
    {"_deg", "deg"},
    {"_rad", "rad"},
    {"_ms", "ms"},
    {"_us", "us"},
    {"_hz", "Hz"},
    {"_m2", "m²"},
    {"_pct", "%"},
    {"_s", "s"},
    {"_l", "L"},
};

bool ends_with(std::string_view s, std::string_view tail) {
  return s.size() > tail.size() && s.substr(s.size() - tail.size()) == tail;
}

// `keys` is the last dotted part(s) of `rest`: "a.b.keys", not "a.bkeys".
bool ends_with_key(std::string_view rest, std::string_view keys) {
  return ends_with(rest, keys) && rest[rest.size() - keys.size() - 1] == '.';
}

// The keys of an axis path without its list indices: "campaign.gap.changes[0].drift.to_deg" ->
// {campaign, gap, changes, drift, to_deg}.
std::vector<std::string> keys_of(const std::string& path) {
  std::vector<std::string> keys;
  std::string key;
  bool in_index = false;
  for (char ch : path) {
    if (ch == '[') in_index = true;
    if (!in_index && ch != '.') key += ch;
    if (ch == ']') in_index = false;
    if (ch == '.' && !key.empty()) keys.push_back(std::exchange(key, {}));
  }
  if (!key.empty()) keys.push_back(key);
  return keys;
}

// A spec's doc as a label: up to its first parenthesis or semicolon ("backlash size sigma (a gap
// cannot be negative)" -> "backlash size sigma").
std::string doc_label(std::string_view doc) {
  const auto cut = std::min(doc.find(" ("), doc.find(';'));
  return std::string(doc.substr(0, cut));
}

std::string spec_label(std::span<const ParamSpec> specs, const std::string& key) {
  for (const ParamSpec& s : specs)
    if (s.key == key) return doc_label(s.doc);
  return "";
}

// The effect's specs as the plan's plant configures it (the specs are the effect instance's).
std::string effect_label(const SweepPlan& plan, const std::string& kind, const std::string& key) {
  const plant::EffectInfo* info = plant::find_effect(kind);
  if (info == nullptr) return "";
  try {
    const cfg::Node plant_node = cfg::Node::load_string(plan.plant_yaml, "plant");
    const auto effects = plant_node.find("effects");
    if (!effects) return "";
    const auto block = effects->find(kind);
    if (!block) return "";
    return spec_label(info->from_yaml(*block)->specs(), key);
  } catch (const std::exception&) {  // a plant the planner accepted; words are no reason to fail
    return "";
  }
}

std::string key_words(std::string key) {
  const std::string unit = unit_of_key(key);
  for (const auto& [suffix, u] : kUnitSuffixes) {
    if (!unit.empty() && u == unit && ends_with(key, suffix)) {
      key.resize(key.size() - suffix.size());
      break;
    }
  }
  std::replace(key.begin(), key.end(), '_', ' ');
  return key;
}

void check_line(const cfg::Node& n, const std::string& text, std::size_t max_chars) {
  n.require(!text.empty(), "must not be empty");
  n.require(text.find_first_of("\n\r\t") == std::string::npos, "must be one line of text");
  n.require(text.size() <= max_chars, "at most " + std::to_string(max_chars) + " characters");
}

}  // namespace

void read_axis_words(const cfg::Node& axis, SweepAxis& a) {
  if (auto l = axis.find("label")) {
    l->require(l->is_scalar(), "must be a text");
    a.label = l->text();
    check_line(*l, a.label, kMaxLabelChars);
  }
  if (auto u = axis.find("unit")) {
    u->require(u->is_scalar(), "must be a text");
    a.unit = u->text();
    check_line(*u, a.unit, kMaxUnitChars);
  }
}

void read_map_bound(const cfg::Node& map_node, SweepMap& map) {
  if (map_node.has("min")) map.min = map_node.number("min");
  if (map_node.has("max")) map.max = map_node.number("max");
  if (map.min && map.max) map_node.at("max").require(*map.max >= *map.min, "must be >= min");
}

void axis_words_to_json(const SweepAxis& a, json& j) {
  if (!a.label.empty()) j["label"] = a.label;
  if (!a.unit.empty()) j["unit"] = a.unit;
}

void axis_words_from_json(const json& j, SweepAxis& a) {
  if (j.contains("label")) a.label = j.at("label").get<std::string>();
  if (j.contains("unit")) a.unit = j.at("unit").get<std::string>();
}

void map_bound_to_json(const SweepMap& m, json& j) {
  if (m.min) j["min"] = *m.min;
  if (m.max) j["max"] = *m.max;
}

void map_bound_from_json(const json& j, SweepMap& m) {
  if (j.contains("min")) m.min = j.at("min").get<double>();
  if (j.contains("max")) m.max = j.at("max").get<double>();
}

std::string unit_of_key(const std::string& key) {
  for (const auto& [suffix, unit] : kUnitSuffixes)
    if (ends_with(key, suffix)) return std::string(unit);
  return "";
}

AxisWords axis_words(const SweepPlan& plan, const SweepAxis& a) {
  const auto keys = keys_of(a.path);
  AxisWords w;
  bool says_increment = false;  // the label names the increment itself ("gap growth")
  if (!keys.empty()) {
    const std::string& key = keys.back();
    w.unit = unit_of_key(key);
    if (keys.size() == 4 && keys[0] == "plant" && keys[1] == "effects") {
      w.label = effect_label(plan, keys[2], key);
    } else if (keys.size() == 3 && keys[0] == "controller") {
      if (const ctl::CompensatorInfo* c = ctl::find_compensator(keys[1])) w.label = spec_label(c->specs, key);
    }
    if (w.label.empty() && keys[0] != "plant") {
      std::string rest;  // the keys after campaign./controller., joined by '.'
      for (std::size_t i = 1; i < keys.size(); ++i) {
        if (!rest.empty()) rest += '.';
        rest += keys[i];
      }
      for (const CampaignKey& k : kCampaignKeys) {
        if (rest == k.keys || ends_with_key(rest, k.keys)) {
          says_increment = !a.relative_to.empty() && !k.relative.empty();
          w.label = says_increment ? k.relative : k.label;
          break;
        }
      }
    }
    if (w.label.empty()) w.label = key_words(key);
  }
  if (w.label.empty()) w.label = a.path;
  if (!a.relative_to.empty() && !says_increment) {
    SweepAxis base;
    base.path = a.relative_to;
    w.label += ", added to the " + axis_words(plan, base).label;
  }
  if (!a.label.empty()) w.label = a.label;
  if (!a.unit.empty()) w.unit = a.unit;
  return w;
}

bool MapBound::holds(double v) const { return std::isfinite(v) && (!min || v >= *min) && (!max || v <= *max); }

MapBound map_bound(const SweepPlan& plan, const SweepMap& map) {
  if (map.min || map.max) return {map.min, map.max};
  for (const auto& t : plan.thresholds)
    if (t.metric == map.metric) return {t.min, t.max};
  return {};
}

}  // namespace hil::bench
