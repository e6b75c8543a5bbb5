#include "hil/param_spec.hpp"

#include "hil/config.hpp"

namespace hil {

namespace {

double read_value(const cfg::Node& node, const ParamSpec& p) {
  const double v = p.whole ? static_cast<double>(node.integer()) : node.number();
  node.require(param_in_range(p, v), std::string(p.doc) + ": must be " + (p.whole ? "" : "in ") + param_range_text(p));
  return v;
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
    values.push_back(read_value(*node, p));
  }
  return values;
}

void apply_params(const cfg::Node& block, std::span<const ParamSpec> specs, std::vector<double>& values) {
  if (block.is_null()) return;
  std::vector<std::string> allowed;
  for (const auto& p : specs) allowed.emplace_back(p.key);
  block.allow_keys(allowed);
  for (std::size_t i = 0; i < specs.size() && i < values.size(); ++i) {
    if (auto node = block.find(specs[i].key)) values[i] = read_value(*node, specs[i]);
  }
}

}  // namespace hil
