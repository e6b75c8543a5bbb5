// The hilbench sub-commands. Each define_X declares X's arguments on its CLI11 sub-command and
// returns the job to run once they are parsed, which returns the process exit code. Usage errors
// past parsing throw UsageError, configuration errors cfg::Error; main.cpp maps them to exit codes.
#pragma once

#include <filesystem>
#include <string>

#include "cli.hpp"

namespace hil::bench {

CommandRun define_sim(CLI::App& cmd);
CommandRun define_run(CLI::App& cmd);
CommandRun define_sweep(CLI::App& cmd);
CommandRun define_effects(CLI::App& cmd);
CommandRun define_compensators(CLI::App& cmd);
CommandRun define_serve(CLI::App& cmd);
CommandRun define_ctl(CLI::App& cmd);
CommandRun define_compare(CLI::App& cmd);
CommandRun define_diagnose(CLI::App& cmd);
CommandRun define_characterise(CLI::App& cmd);
CommandRun define_plant(CLI::App& cmd);
CommandRun define_report(CLI::App& cmd);
CommandRun define_drive(CLI::App& cmd);

// The characterisation table (markdown) of the observers on the paper's scenarios.
std::string characterise_table(const std::filesystem::path& campaigns_dir);

}  // namespace hil::bench
