// A scalar parameter of a registered part (a plant effect, a compensator): its YAML key with the
// unit, its physical range, its default. One type and one checker for every kind of part, so a
// range error reads the same wherever it is made. Header-only but for read_params, which reads
// YAML (hil_common): a room that may link nothing of ours (controller/) checks values with it.
#pragma once

#include <cmath>
#include <cstdio>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace hil {

namespace cfg {
class Node;
}

// One scalar parameter, in the unit its YAML key names (degrees, mm², kPa...).
struct ParamSpec {
  std::string_view key;   // YAML key, carries the unit: "gap_deg"
  double lo, hi;          // physically possible range
  bool lo_open, hi_open;  // whether lo/hi themselves are excluded
  double fallback;        // used when the key is absent; NaN = required
  std::string_view doc;   // one line, used in error messages and in docs
  bool whole = false;     // a count (samples, tries): a whole number
};

inline bool param_in_range(const ParamSpec& p, double v) noexcept {
  const bool lo_ok = p.lo_open ? v > p.lo : v >= p.lo;
  const bool hi_ok = p.hi_open ? v < p.hi : v <= p.hi;
  return std::isfinite(v) && lo_ok && hi_ok && (!p.whole || v == std::floor(v));
}

inline std::string param_number_text(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

// "[0, 10]", "(0, 1]", "a whole number in [1, 1000]".
inline std::string param_range_text(const ParamSpec& p) {
  return std::string(p.whole ? "a whole number in " : "") + (p.lo_open ? "(" : "[") + param_number_text(p.lo) + ", " +
         param_number_text(p.hi) + (p.hi_open ? ")" : "]");
}

// Validates values against specs (fitting, programmatic construction); throws
// std::invalid_argument naming kind.key.
inline void check_params(std::string_view kind, std::span<const ParamSpec> specs, std::span<const double> values) {
  if (values.size() != specs.size()) {
    throw std::invalid_argument(std::string(kind) + ": expected " + std::to_string(specs.size()) + " parameters, got " +
                                std::to_string(values.size()));
  }
  for (std::size_t i = 0; i < specs.size(); ++i) {
    if (!param_in_range(specs[i], values[i])) {
      throw std::invalid_argument(std::string(kind) + "." + std::string(specs[i].key) + " = " + param_number_text(values[i]) +
                                  ": must be " + (specs[i].whole ? "" : "in ") + param_range_text(specs[i]));
    }
  }
}

// The defaults of `specs` (NaN where a key is required).
inline std::vector<double> param_defaults(std::span<const ParamSpec> specs) {
  std::vector<double> values;
  for (const auto& p : specs) values.push_back(p.fallback);
  return values;
}

// Reads and validates the scalar params of `specs` from a YAML block (located errors); absent
// keys take their fallback, a required one (NaN) is an error.
std::vector<double> read_params(const cfg::Node& block, std::span<const ParamSpec> specs,
                                std::span<const std::string_view> extra_keys = {});
// The keys of `block` that `specs` names overwrite `values` (same order as specs), each checked
// against its range: a run's block over its campaign's. Other keys are an error.
void apply_params(const cfg::Node& block, std::span<const ParamSpec> specs, std::vector<double>& values);

}  // namespace hil
