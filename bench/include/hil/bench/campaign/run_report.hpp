// The paper-style report of runs recorded by `hilbench serve` (one run folder each): the same
// figures and metrics as `hilbench sim`'s campaign report, so a run on a rig is reviewed the
// same way as a simulation. The campaign comes from the run's own config snapshot (run.json).
#pragma once

#include <filesystem>
#include <vector>

#include "hil/bench/campaign/sim.hpp"

namespace hil::bench {

struct RecordedRun {
  std::filesystem::path dir;
  std::string outcome, reason;
  RunOutcome digest;  // metrics and report series, from telemetry.csv
};

// Reads the runs (all of one campaign) and writes the report to `out_file`. Throws naming the
// folder or the file at fault (a missing run.json, a telemetry.csv the strict reader refuses,
// runs of different campaigns, a campaign whose plant file is gone).
std::vector<RecordedRun> write_run_report(const std::vector<std::filesystem::path>& run_dirs,
                                          const std::filesystem::path& out_file);

}  // namespace hil::bench
