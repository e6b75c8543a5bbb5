#include "hil/bench/rt/rig_registry.hpp"

#include "hil/config.hpp"
#include "hil/registry.hpp"

namespace hil::bench {

bool register_rig_kind(std::string_view kind, RigKindInfo info) {
  // The kind's view points at the registry's own copy of the name, which outlives every caller.
  if (info.devices.drive) info.capabilities = capabilities_of(info.devices);
  auto [name, kept] = Registry<RigKindInfo>::add(kind, info);
  kept.kind = name;
  return true;
}

const RigKindInfo* find_rig_kind(std::string_view kind) { return Registry<RigKindInfo>::find(kind); }

std::vector<std::string> rig_kind_names() { return Registry<RigKindInfo>::names(); }

std::string unknown_rig_kind_text(std::string_view kind) {
  const std::vector<std::string> names = rig_kind_names();
  const std::string hint = cfg::closest(kind, names);
  std::string known;
  for (const auto& n : names) known += (known.empty() ? "" : ", ") + n;
  return "unknown rig kind '" + std::string(kind) + "'" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)") +
         "; this build knows: " + (known.empty() ? "none" : known);
}

}  // namespace hil::bench
