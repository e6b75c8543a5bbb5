// The hilbench sub-commands. Each takes its arguments after the command name and returns the
// process exit code; usage errors throw UsageError, configuration errors throw cfg::Error.
#pragma once

#include <string>
#include <vector>

namespace hil::bench {

int cmd_sim(const std::vector<std::string>& args);
int cmd_effects(const std::vector<std::string>& args);
int cmd_serve(const std::vector<std::string>& args);
int cmd_ctl(const std::vector<std::string>& args);
int cmd_compare(const std::vector<std::string>& args);
int cmd_diagnose(const std::vector<std::string>& args);

}  // namespace hil::bench
