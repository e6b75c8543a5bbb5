// What a sweep's report calls its axes and maps: an axis's label and unit ("initial gap", "deg")
// from the sweep file's `label:`/`unit:`, else from the parameter specs of the part the path
// names (the plant's effects, the compensators) or the campaign's own keys, the unit read off the
// key's suffix (names carry units). And a map's own threshold (`min:`/`max:` in the map).
// The sweep file's reader (sweep.cpp) and plan.json call the read/json helpers; the report the
// rest. Not real-time: allocates.
#pragma once

#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "hil/bench/campaign/sweep.hpp"
#include "hil/config.hpp"

namespace hil::bench {

// The axis's `label:` and `unit:` (each optional), checked: one line of text, a label of at most
// 80 characters and a unit of at most 16; errors name the sweep file, line and key.
void read_axis_words(const cfg::Node& axis, SweepAxis& a);
// The map's `min:` and `max:` (each optional, a number; max >= min).
void read_map_bound(const cfg::Node& map_node, SweepMap& map);
// plan.json's fields for both: written when set, read when present (older plans have none).
void axis_words_to_json(const SweepAxis& a, nlohmann::json& j);
void axis_words_from_json(const nlohmann::json& j, SweepAxis& a);
void map_bound_to_json(const SweepMap& m, nlohmann::json& j);
void map_bound_from_json(const nlohmann::json& j, SweepMap& m);

// The unit a key's suffix names ("gap_deg" -> "deg", "noise_rms_kpa" -> "kPa"); "" for none.
std::string unit_of_key(const std::string& key);

struct AxisWords {
  std::string label, unit;  // unit "" when the value has none (a seed, a ratio)
  // "initial gap (deg)", or the label alone without a unit.
  std::string title() const { return unit.empty() ? label : label + " (" + unit + ")"; }
};
// The axis's words: the file's, else the defaults (the plan's plant YAML gives the effects' specs).
AxisWords axis_words(const SweepPlan& plan, const SweepAxis& a);

// A map's threshold: its own min/max if it has one, else the sweep's threshold of its metric.
struct MapBound {
  std::optional<double> min, max;
  bool any() const { return min.has_value() || max.has_value(); }
  bool holds(double v) const;  // false for NaN
};
MapBound map_bound(const SweepPlan& plan, const SweepMap& map);

}  // namespace hil::bench
