// The campaign's checks (campaign/checks.hpp) on a served run: fed every row the recorder writes,
// on the recorder's thread (never the loop's), and judged when the run ends, with the same
// evaluator as `hilbench sim` and a sweep point. The runner's thin hook: it passes sink() as the
// recorder's row sink and writes finish() into run.json and its status.
#pragma once

#include <nlohmann/json.hpp>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/campaign/checks.hpp"
#include "hil/bench/campaign/run_metrics.hpp"
#include "hil/bench/rt/recorder.hpp"

namespace hil::bench {

class RunVerdicts {
 public:
  // `knows_truth`: the rig records the chamber pressure and the valve angle (else the IAE is of
  // the measured pressure and the stall unknown, as `hilbench report` has them). `downstream`:
  // the sink the rows went to before (the live telemetry), called after the checks see the row.
  RunVerdicts(const Campaign& c, const RunSpec& run, bool knows_truth, Recorder::RowSink downstream);
  RunVerdicts(const RunVerdicts&) = delete;
  RunVerdicts& operator=(const RunVerdicts&) = delete;

  Recorder::RowSink sink();
  // Once the recorder has finished: the verdicts (checks_json), or null when the campaign has no
  // checks. `pressure_trip`: the run ended on an over- or underpressure interlock.
  nlohmann::json finish(bool pressure_trip, const RunChecks::OtherRun& other);
  const RunSummary& summary() const { return summary_; }

 private:
  bool active_, knows_truth_;
  long rows_ = 0;  // rows seen (none: the run never reached its loop, every check is skipped)
  RunMetrics metrics_;
  RunChecks checks_;
  Recorder::RowSink downstream_;
  RunSummary summary_;
};

}  // namespace hil::bench
