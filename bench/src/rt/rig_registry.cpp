#include "hil/bench/rt/rig_registry.hpp"

#include <map>

#include "hil/config.hpp"

namespace hil::bench {
namespace {
// A function-local table: kinds register from other translation units' static initialisers,
// whose order against this one's is unspecified.
std::map<std::string, RigKindInfo, std::less<>>& table() {
  static std::map<std::string, RigKindInfo, std::less<>> kinds;
  return kinds;
}
}  // namespace

bool register_rig_kind(std::string_view kind, RigKindInfo info) {
  auto& t = table();
  const auto [it, added] = t.emplace(std::string(kind), info);
  // The view points at the table's own key, which lives as long as the table.
  if (added) it->second.kind = it->first;
  return true;
}

const RigKindInfo* find_rig_kind(std::string_view kind) {
  const auto it = table().find(kind);
  return it == table().end() ? nullptr : &it->second;
}

std::vector<std::string> rig_kind_names() {
  std::vector<std::string> names;
  for (const auto& [name, info] : table()) names.push_back(name);
  return names;
}

std::string unknown_rig_kind_text(std::string_view kind) {
  const std::vector<std::string> names = rig_kind_names();
  const std::string hint = cfg::closest(kind, names);
  std::string known;
  for (const auto& n : names) known += (known.empty() ? "" : ", ") + n;
  return "unknown rig kind '" + std::string(kind) + "'" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)") +
         "; this build knows: " + (known.empty() ? "none" : known);
}

}  // namespace hil::bench
