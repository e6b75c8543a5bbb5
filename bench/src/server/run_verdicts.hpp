// The campaign's checks (campaign/checks.hpp) on a served run: fed every row the recorder writes,
// on the recorder's thread (never the loop's), and judged when the run ends, with the same
// evaluator as `hilbench sim` and a sweep point. The runner's thin hook: it passes sink() as the
// recorder's row sink and writes finish() into run.json and its status.
//
// While the run goes on, live() gives the verdicts as they stand (RunChecks::live: a failed signal
// check at once, a window's verdict when it closes, metrics pending until the end) for the
// runner's status, which the status stream pushes to the console. The recorder's thread hands a
// copy of the evaluator's progress (its windows, O(checks)) over at most every kLiveEvery; live()
// judges that copy on the caller's thread. Per run that is O(rows x checks) for add(), as before,
// plus O(checks) per hand-over and per call: linear in the run's length.
#pragma once

#include <chrono>
#include <mutex>

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
  // Any thread, while the run goes on: {"run", "t_s" (the last row handed over, null before
  // one), "results": [LiveCheck::to_json...]}, or null when the campaign has no checks.
  nlohmann::json live() const;

  static constexpr std::chrono::milliseconds kLiveEvery{50};

 private:
  bool active_, knows_truth_;
  long rows_ = 0;  // rows seen (none: the run never reached its loop, every check is skipped)
  RunMetrics metrics_;
  RunChecks checks_;
  Recorder::RowSink downstream_;
  RunSummary summary_;
  mutable std::mutex live_mutex_;
  RunChecks::Progress live_;                       // the recorder thread's copy for live(); under live_mutex_
  std::chrono::steady_clock::time_point live_at_;  // when it was copied (the recorder's thread only)
};

}  // namespace hil::bench
