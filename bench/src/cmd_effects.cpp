// hilbench effects: every physical effect a plant file may use, with its parameters.
#include <cmath>
#include <cstdio>

#include "cli.hpp"
#include "commands.hpp"
#include "hil/plant/registry.hpp"

namespace hil::bench {

int cmd_effects(const std::vector<std::string>& argv) {
  (void)parse_args(argv, {}, {});
  for (const auto& name : plant::effect_names()) {
    const plant::EffectInfo* info = plant::find_effect(name);
    std::printf("%-16s %s\n", name.c_str(), std::string(info->doc).c_str());
  }
  return 0;
}

}  // namespace hil::bench
