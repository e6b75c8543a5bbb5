// hilbench effects [NAME...]: the physical effects a plant file may use (`effects:` keys), each
// with its parameters (key with its unit, range, default, meaning) as `compensators` prints them;
// with names, only those.
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "cmd_shared.hpp"
#include "commands.hpp"
#include "hil/plant/registry.hpp"

namespace hil::bench {

CommandRun define_effects(CLI::App& cmd) {
  auto names = std::make_shared<std::vector<std::string>>();
  cmd.add_option("NAME", *names, "only these effects (default: every one)");
  return [names] {
    std::vector<std::string> shown = names->empty() ? plant::effect_names() : *names;
    for (const auto& name : shown) {
      if (plant::find_effect(name) != nullptr) continue;
      std::string known;
      for (const auto& n : plant::effect_names()) known += (known.empty() ? "" : ", ") + n;
      throw UsageError("unknown effect '" + name + "' (known: " + known +
                       "; an effect added to the sources needs `scripts/build.sh hilbench` first)");
    }
    for (const auto& name : shown) {
      const plant::EffectInfo* info = plant::find_effect(name);
      std::printf("%-16s %s\n", name.c_str(), std::string(info->doc).c_str());
      print_param_specs(info->specs);
      if (!info->tables_doc.empty()) std::printf("  lists: %s\n", std::string(info->tables_doc).c_str());
      if (info->specs.empty() && info->tables_doc.empty()) std::printf("  (no parameters)\n");
    }
    return 0;
  };
}

}  // namespace hil::bench
