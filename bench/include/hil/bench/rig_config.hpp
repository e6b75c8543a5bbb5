// A rig file (configs/rigs/*.yaml, documented in place): which rig, its loop (priority, CPU,
// overrun policy) and its safety interlocks. Validated at load: errors name file:line:key.
#pragma once

#include <filesystem>
#include <memory>
#include <string>

#include "hil/bench/rig.hpp"
#include "hil/bench/rt_loop.hpp"
#include "hil/bench/safety.hpp"

namespace hil::bench {

struct RigConfig {
  std::string name;         // the file's stem
  std::string kind;         // sim (cia402 and modbus come with their issue)
  std::string description;
  std::filesystem::path file;
  LoopConfig loop;
  SafetyConfig safety;
  std::string yaml_text;    // the file as loaded, for the run's snapshot
};

RigConfig load_rig_config(const std::filesystem::path& file);
RigConfig load_rig_config_text(const std::string& yaml, const std::string& origin);

// A new, unconfigured rig of the file's kind. Throws naming the kind when it is unknown.
std::unique_ptr<Rig> make_rig(const RigConfig& config);

}  // namespace hil::bench
