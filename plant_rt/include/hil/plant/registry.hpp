// Effects are created by name from their YAML block. An effect registers itself with
// HIL_REGISTER_EFFECT in its own .cpp; the plant library is linked whole so that every
// registration runs (see plant_rt/CMakeLists.txt).
#pragma once

#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "hil/plant/effect.hpp"

namespace hil::plant {

struct EffectInfo {
  std::string_view kind;
  Stage stage;
  std::shared_ptr<const Effect> (*from_yaml)(const cfg::Node& block);
  std::string_view doc;
  std::span<const ParamSpec> specs = {};  // its scalar parameters (Class::kSpecs), for `hilbench effects`
  std::string_view tables_doc = "";       // its keys that are lists (Class::kTablesDoc), if any
};

// What HIL_REGISTER_EFFECT takes of a class: its kSpecs and kTablesDoc where it has them.
template <class Class>
constexpr std::span<const ParamSpec> registered_specs() {
  if constexpr (requires { Class::kSpecs; })
    return Class::kSpecs;
  else
    return {};
}
template <class Class>
constexpr std::string_view registered_tables_doc() {
  if constexpr (requires { Class::kTablesDoc; })
    return Class::kTablesDoc;
  else
    return {};
}

bool register_effect(const EffectInfo& info);
const EffectInfo* find_effect(std::string_view kind);
std::vector<std::string> effect_names();

}  // namespace hil::plant

#define HIL_REGISTER_EFFECT(Class, doc_text)                                                                                  \
  namespace {                                                                                                                 \
  [[maybe_unused]] const bool registered_##Class =                                                                            \
      ::hil::plant::register_effect({Class::kKind, Class::kStage, &Class::from_yaml, doc_text,                                \
                                     ::hil::plant::registered_specs<Class>(), ::hil::plant::registered_tables_doc<Class>()}); \
  }
