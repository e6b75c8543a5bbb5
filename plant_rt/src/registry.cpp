#include "hil/plant/registry.hpp"

#include <algorithm>
#include <map>

namespace hil::plant {
namespace {
std::map<std::string, EffectInfo, std::less<>>& table() {
  static std::map<std::string, EffectInfo, std::less<>> effects;
  return effects;
}
}  // namespace

bool register_effect(const EffectInfo& info) {
  table().emplace(std::string(info.kind), info);
  return true;
}

const EffectInfo* find_effect(std::string_view kind) {
  const auto it = table().find(kind);
  return it == table().end() ? nullptr : &it->second;
}

std::vector<std::string> effect_names() {
  std::vector<std::string> names;
  for (const auto& [name, info] : table()) names.push_back(name);
  return names;
}

}  // namespace hil::plant
