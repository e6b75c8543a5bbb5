#include "hil/plant/effect.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "hil/config.hpp"

namespace hil::plant {
namespace {

bool in_range(const ParamSpec& p, double v) {
  const bool lo_ok = p.lo_open ? v > p.lo : v >= p.lo;
  const bool hi_ok = p.hi_open ? v < p.hi : v <= p.hi;
  return std::isfinite(v) && lo_ok && hi_ok;
}

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

std::string range_text(const ParamSpec& p) {
  return std::string(p.lo_open ? "(" : "[") + num(p.lo) + ", " + num(p.hi) + (p.hi_open ? ")" : "]");
}

}  // namespace

std::vector<double> read_params(const cfg::Node& block, std::span<const ParamSpec> specs,
                                std::span<const std::string_view> extra_keys) {
  std::vector<std::string> allowed;
  for (const auto& p : specs) allowed.emplace_back(p.key);
  for (const auto& k : extra_keys) allowed.emplace_back(k);
  if (block.is_null() && specs.empty()) return {};
  block.allow_keys(allowed);
  std::vector<double> values;
  for (const auto& p : specs) {
    auto node = block.find(p.key);
    if (!node) {
      if (std::isnan(p.fallback)) block.fail("missing required key '" + std::string(p.key) + "' (" + std::string(p.doc) + ")");
      values.push_back(p.fallback);
      continue;
    }
    const double v = node->number();
    node->require(in_range(p, v), std::string(p.doc) + ": must be in " + range_text(p));
    values.push_back(v);
  }
  return values;
}

void check_params(std::string_view kind, std::span<const ParamSpec> specs, std::span<const double> values) {
  if (values.size() != specs.size()) {
    throw std::invalid_argument(std::string(kind) + ": expected " + std::to_string(specs.size()) + " parameters, got " +
                                std::to_string(values.size()));
  }
  for (std::size_t i = 0; i < specs.size(); ++i) {
    if (!in_range(specs[i], values[i])) {
      throw std::invalid_argument(std::string(kind) + "." + std::string(specs[i].key) + " = " + num(values[i]) + ": must be in " +
                                  range_text(specs[i]));
    }
  }
}

}  // namespace hil::plant
