// hilbench compensators: every compensator a campaign may name (`compensator:`), with its
// parameters (the keys of its block in the controller section), their ranges and defaults.
#include <cmath>
#include <cstdio>
#include <string>

#include "cmd_shared.hpp"
#include "commands.hpp"
#include "hil/ctl/compensator.hpp"

namespace hil::bench {

void print_param_specs(std::span<const ParamSpec> specs) {
  for (const ParamSpec& p : specs) {
    const std::string fallback = std::isnan(p.fallback) ? "required" : "default " + param_number_text(p.fallback);
    std::printf("  %-24s %-28s %-16s %s\n", std::string(p.key).c_str(), param_range_text(p).c_str(), fallback.c_str(),
                std::string(p.doc).c_str());
  }
}

CommandRun define_compensators(CLI::App&) {
  return [] {
    for (const auto& name : ctl::compensator_names()) {
      const ctl::CompensatorInfo* info = ctl::find_compensator(name);
      std::printf("%-12s %s\n", name.c_str(), std::string(info->doc).c_str());
      print_param_specs(info->specs);
    }
    return 0;
  };
}

}  // namespace hil::bench
