// Effects are created by name from their YAML block. An effect registers itself with
// HIL_REGISTER_EFFECT in its own .cpp; the plant library is linked whole so that every
// registration runs (see plant_rt/CMakeLists.txt).
#pragma once

#include <memory>
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
};

bool register_effect(const EffectInfo& info);
const EffectInfo* find_effect(std::string_view kind);
std::vector<std::string> effect_names();

}  // namespace hil::plant

#define HIL_REGISTER_EFFECT(Class, doc_text)                                                     \
  namespace {                                                                                    \
  [[maybe_unused]] const bool registered_##Class =                                               \
      ::hil::plant::register_effect({Class::kKind, Class::kStage, &Class::from_yaml, doc_text}); \
  }
