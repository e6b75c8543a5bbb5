// Offline campaigns: the plant and the controller in lock-step, faster than real time
// (`hilbench sim`). Per run it writes DIR/<campaign>/<run>/telemetry.csv (the measurement schema
// of physics.md section 4 plus the simulation's internals) and summary.json; per campaign a
// report.html comparing the runs. Output appears atomically: a campaign folder is complete or
// absent.
#pragma once

#include <array>
#include <cstdint>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/rt/rt_loop.hpp"
#include "hil/bench/campaign/run_marks.hpp"
#include "hil/bench/campaign/run_metrics.hpp"
#include "hil/bench/rt/sim_rig.hpp"
#include "hil/bench/rt/telemetry_record.hpp"
#include "hil/units.hpp"

namespace hil::bench {

// One run on the simulated rig in simulated time: the bench's own period (RunLoop::cycle) on a
// SimRig, paced by a counter instead of a clock, as fast as the machine goes, with no interlocks
// (SafetyConfig::none) and no operator. Every period gives one record.
class SimulatedRun {
 public:
  // Setup: builds and settles the plant at the reference and gap of t = 0, then the controller.
  SimulatedRun(const Campaign& c, const RunSpec& run);
  SimulatedRun(const SimulatedRun&) = delete;
  SimulatedRun& operator=(const SimulatedRun&) = delete;

  // Runs the next period and hands its record to on_record(const TelemetryRecord&), read where
  // the loop left it; false once the run is over. Real-time safe when on_record is.
  template <class OnRecord>
  bool next(OnRecord&& on_record) {
    return advance() && telemetry_.consume(1, on_record) == 1;
  }

 private:
  bool advance() noexcept;  // one period; false once the run is over

  SimRig rig_;
  SpscRing<TelemetryRecord> telemetry_;
  SpscRing<LoopEvent> events_;
  SpscRing<LoopRequest> requests_;
  RunLoop loop_;
  Clock::time_point t_{};
};

// Runs one campaign run; calls on_step(const TelemetryRecord&) every control period. Counts
// finished steps into steps_done (relaxed, every 1024 steps) when given.
template <class OnStep>
void simulate_run(const Campaign& c, const RunSpec& run, OnStep&& on_step, std::atomic<long>* steps_done = nullptr) {
  SimulatedRun sim(c, run);
  long k = 0;
  while (sim.next(on_step)) {
    if (steps_done != nullptr && (++k & 1023) == 0) steps_done->fetch_add(1024, std::memory_order_relaxed);
  }
  // The last, partial block too: a finished run has counted all its steps (a progress line's 100 %).
  if (steps_done != nullptr) steps_done->fetch_add(k & 1023, std::memory_order_relaxed);
}

// The motor "moves" above this speed in the run metrics: noise makes it creep slower.
inline constexpr double kMotionThresholdRadS = 0.5 * units::kRadPerDeg;  // 0.5 deg/s

// The reversal metrics of a run without writing anything (tests, benchmarks, the README table).
RunSummary summarise_run(const Campaign& c, const RunSpec& run);
// The same, handing each period's record to also(const TelemetryRecord&) as well (a sweep's
// interlock count).
template <class Also>
RunSummary summarise_run(const Campaign& c, const RunSpec& run, Also&& also) {
  RunMetrics metrics(c.reversals_s, c.reference_moves, c.period_s, kMotionThresholdRadS);
  simulate_run(c, run, [&](const TelemetryRecord& r) {
    metrics.add(r.step);
    also(r);
  });
  return metrics.finish();
}

// A series kept for the report: at most ~2 points per bucket (the bucket's min and max, in time
// order), so an hour at 1 kHz stays a few thousand points with every spike kept.
struct ReportSeries {
  std::string name;
  std::vector<double> t_s, value;
  std::size_t samples = 0;  // the rows these points stand for
};

struct RunOutcome {
  std::string name;
  RunSummary summary;
  std::vector<ReportSeries> series;  // p_ref, p_meas, touch, motor, valve, cmd, gap_est, gap_true, target
  double wall_s = 0;
  std::vector<CheckResult> checks;  // the campaign's checks of this run (`hilbench sim`; empty: none)
  RunMarks marks;                   // what happened, marked in the report (run_marks.hpp)
  bool marks_recorded = false;      // marks from the run's events.jsonl, not from the programme
  std::string detail_run;           // a recorded run's folder name: its served report fetches zoomed detail from it
};

// What a run's report and summary are made of, gathered from its records one period at a time:
// the metrics (RunMetrics) and the min/max-decimated series the report plots. One for
// `hilbench sim` (while it simulates) and `hilbench report` (from a recorded telemetry.csv).
class RunDigest {
 public:
  explicit RunDigest(const Campaign& c);
  ~RunDigest();
  RunDigest(const RunDigest&) = delete;
  RunDigest& operator=(const RunDigest&) = delete;
  void add(const TelemetryRecord& r);
  RunOutcome finish(std::string run_name);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct SimOptions {
  std::filesystem::path out_dir = "out";
  bool telemetry = true;
  bool progress = true;
  std::vector<std::string> only_runs;  // empty: all
  // Set (by a signal handler, say) to stop: the campaign throws Cancelled and leaves nothing.
  const std::atomic<bool>* cancel = nullptr;
};

struct Cancelled : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct CampaignOutcome {
  std::filesystem::path dir;  // DIR/<campaign>
  std::vector<RunOutcome> runs;
  double wall_s = 0;
  double simulated_s = 0;  // summed over runs
};

// Throws std::runtime_error on I/O failure (the campaign folder is then left as it was).
CampaignOutcome run_campaign(const Campaign& c, const SimOptions& options);

}  // namespace hil::bench
