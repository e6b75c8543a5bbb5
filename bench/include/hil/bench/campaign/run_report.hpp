// The paper-style report of runs recorded by `hilbench serve` (one run folder each): the same
// figures and metrics as `hilbench sim`'s campaign report, so a run on a rig is reviewed the
// same way as a simulation. The campaign comes from the run's own config snapshot (run.json).
#pragma once

#include <atomic>
#include <filesystem>
#include <functional>
#include <vector>

#include "hil/bench/campaign/sim.hpp"

namespace hil::bench {

struct RecordedRun {
  std::filesystem::path dir;
  std::string outcome, reason;
  RunOutcome digest;  // metrics and report series, from telemetry.csv
};

struct RunReportOptions {
  // Called after each chunk of rows with the fraction of the runs' telemetry read so far (0..1).
  std::function<void(double fraction)> progress;
  // Set from another thread (a server shutting down, a signal): throws Cancelled (sim.hpp) before
  // the next chunk of rows, having written nothing.
  const std::atomic<bool>* cancel = nullptr;
};

// Reads the runs (all of one campaign) and writes the report to `out_file`. The telemetry is
// streamed in chunks of rows into the runs' digests, so memory stays bounded however long a run
// was (an hour at 1 kHz is 3.6 M rows; read whole, several hundred MB, locked by the server's
// mlockall). Throws naming the folder or the file at fault (a missing run.json, a telemetry.csv
// the strict reader refuses, runs of different campaigns, a campaign whose plant file is gone).
std::vector<RecordedRun> write_run_report(const std::vector<std::filesystem::path>& run_dirs,
                                          const std::filesystem::path& out_file, const RunReportOptions& options = {});

}  // namespace hil::bench
