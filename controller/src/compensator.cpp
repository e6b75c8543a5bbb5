#include "hil/ctl/compensator.hpp"

#include <stdexcept>

#include "hil/registry.hpp"

namespace hil::ctl {

bool register_compensator(const CompensatorInfo& info) {
  Registry<CompensatorInfo>::add(info.name, info);
  return true;
}

const CompensatorInfo* find_compensator(std::string_view name) { return Registry<CompensatorInfo>::find(name); }

std::vector<std::string> compensator_names() { return Registry<CompensatorInfo>::names(); }

std::shared_ptr<const Compensator> make_compensator(std::string_view name, const CompensatorSetup& setup,
                                                    std::span<const double> values) {
  const CompensatorInfo* info = find_compensator(name);
  if (info == nullptr) {
    std::string known;
    for (const auto& n : compensator_names()) known += (known.empty() ? "" : ", ") + n;
    throw std::invalid_argument("controller: no compensator '" + std::string(name) + "'; registered: " + known);
  }
  const std::vector<double> defaults = param_defaults(info->specs);
  if (values.empty()) values = defaults;
  check_params("compensator " + std::string(name), info->specs, values);
  return info->make(setup, values);
}

}  // namespace hil::ctl
