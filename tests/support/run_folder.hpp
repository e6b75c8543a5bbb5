// A run folder as `hilbench serve` leaves it once a run has ended, made without a server: its
// run.json (a completed run of `campaign_yaml` on the simulated rig), as written before run.json
// kept the plant's text, so a report finds the plant by the campaign file's path. The caller puts
// the telemetry.csv beside it.
#pragma once

#include <filesystem>
#include <string>

#include "hil/bench/rt/run_record.hpp"

namespace hil::test {

inline void write_ended_run(const std::filesystem::path& run_dir, const std::string& campaign, const std::string& run,
                            const std::string& campaign_yaml, const std::filesystem::path& campaign_file, double duration_s) {
  bench::RunRecord r;
  r.version = "0.1.0";
  r.campaign = campaign;
  r.run = run;
  r.runs_in_campaign = 1;
  r.rig_name = r.rig_kind = "sim";
  r.start_utc = "2026-11-27T05:00:00.000Z";
  r.stop_utc = "2026-11-27T05:01:10.000Z";
  r.outcome = bench::Outcome::completed;
  r.period_s = 1e-3;
  r.duration_s = duration_s;
  r.config = {campaign_file.filename().string(), campaign_file.string(), campaign_yaml, "", "", "", ""};  // no plant snapshot
  r.ended = true;
  std::filesystem::create_directories(run_dir);
  bench::write_run_record(run_dir, r);
}

}  // namespace hil::test
