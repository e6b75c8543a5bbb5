// hilbench effects: every physical effect a plant file may use, with its parameters.
#include <cstdio>

#include "commands.hpp"
#include "hil/plant/registry.hpp"

namespace hil::bench {

CommandRun define_effects(CLI::App&) {
  return [] {
    for (const auto& name : plant::effect_names()) {
      const plant::EffectInfo* info = plant::find_effect(name);
      std::printf("%-16s %s\n", name.c_str(), std::string(info->doc).c_str());
    }
    return 0;
  };
}

}  // namespace hil::bench
