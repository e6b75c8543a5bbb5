// The hilbench sub-commands. Each takes its arguments after the command name and returns the
// process exit code; usage errors throw UsageError, configuration errors throw cfg::Error.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace hil::bench {

int cmd_sim(const std::vector<std::string>& args);
int cmd_effects(const std::vector<std::string>& args);
int cmd_serve(const std::vector<std::string>& args);
int cmd_ctl(const std::vector<std::string>& args);
int cmd_compare(const std::vector<std::string>& args);
int cmd_diagnose(const std::vector<std::string>& args);
int cmd_characterise(const std::vector<std::string>& args);
int cmd_plant(const std::vector<std::string>& args);
int cmd_report(const std::vector<std::string>& args);
int cmd_drive(const std::vector<std::string>& args);

// The characterisation table (markdown) of the observers on the paper's scenarios.
std::string characterise_table(const std::filesystem::path& campaigns_dir);

}  // namespace hil::bench
