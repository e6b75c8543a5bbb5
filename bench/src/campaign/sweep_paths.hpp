// What the sweep's planning (sweep.cpp) and its points (sweep_point.cpp) share: the path of an
// axis into the campaign or plant YAML, the walk to the value it names, numbers printed so that
// the same value always prints the same, and YAML text parsed with its origin in the error.
#pragma once

#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

namespace hil::bench::sweep_detail {

inline constexpr double kNoValue = std::numeric_limits<double>::quiet_NaN();

// A number as the shortest text that reads back as the same double: the same value always
// prints the same, whatever computed it.
std::string shortest(double v);

// One step of an axis path: a mapping key or a sequence index.
struct Step {
  std::string key;
  long index = -1;  // >= 0: a sequence index
};

struct AxisPath {
  bool plant = false;  // in the plant file, else in the campaign file
  std::vector<Step> steps;
};

// "campaign.gap.changes[0].drift.to_deg" -> campaign file, gap / changes / [0] / drift / to_deg.
// "controller.x" stands for campaign.controller.x. Empty on a malformed path.
std::optional<AxisPath> parse_path(const std::string& text);

// Mutable walk of an already checked path (the tree is a clone of the checked base).
YAML::Node walk_checked(YAML::Node root, const AxisPath& path);

// YAML text parsed; a syntax error is thrown as std::runtime_error naming `origin`.
YAML::Node load_yaml(const std::string& text, const std::string& origin);

}  // namespace hil::bench::sweep_detail
