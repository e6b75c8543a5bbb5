#include "hil/plant/registry.hpp"

#include "hil/registry.hpp"

namespace hil::plant {

bool register_effect(const EffectInfo& info) {
  Registry<EffectInfo>::add(info.kind, info);
  return true;
}

const EffectInfo* find_effect(std::string_view kind) { return Registry<EffectInfo>::find(kind); }

std::vector<std::string> effect_names() { return Registry<EffectInfo>::names(); }

}  // namespace hil::plant
