// The hilbench sub-commands. Each define_X declares X's arguments on its CLI11 sub-command and
// returns the job to run once they are parsed, which returns the process exit code. Usage errors
// past parsing throw UsageError, configuration errors cfg::Error; main.cpp maps them to exit codes.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "cli.hpp"

namespace hil::bench {

struct Campaign;

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

// The runs `--runs LIST` names (`sim`, `run`, `ctl start`): throws UsageError for an empty list
// ('' or ','; it would run every run, the opposite of a choice), an empty name between commas
// (a script's empty variable) and a name given twice. chosen_runs also refuses a name the
// campaign does not have (it was dropped, and the rest ran).
std::vector<std::string> run_names(const std::string& list);
std::vector<std::string> chosen_runs(const Campaign& campaign, const std::string& list);

// The characterisation table (markdown) of the observers on the paper's scenarios.
std::string characterise_table(const std::filesystem::path& campaigns_dir);

}  // namespace hil::bench
