#include "run_verdicts.hpp"

#include <limits>

#include "hil/bench/campaign/sim.hpp"

namespace hil::bench {

RunVerdicts::RunVerdicts(const Campaign& c, const RunSpec& run, bool knows_truth, Recorder::RowSink downstream)
    : active_(!c.checks.empty()),
      knows_truth_(knows_truth),
      metrics_(c.reversals_s, c.reference_moves, c.period_s, kMotionThresholdRadS),
      checks_(c, run.name),
      downstream_(std::move(downstream)),
      live_(checks_.progress()) {}

Recorder::RowSink RunVerdicts::sink() {
  if (!active_) return downstream_;  // no checks: the rows go where they went, nothing added
  return [this](const TelemetryRecord& r) {
    if (knows_truth_) {
      metrics_.add(r.step);
    } else {
      StepRecord s = r.step;  // without the chamber's truth the IAE is of the measured pressure
      s.p_chamber_pa = s.p_meas_pa;
      metrics_.add(s);
    }
    checks_.add(r);
    ++rows_;
    // Handed over at a bounded rate (a copy of the same size: no allocation), not per row.
    if (const auto now = std::chrono::steady_clock::now(); rows_ == 1 || now - live_at_ >= kLiveEvery) {
      std::lock_guard lock(live_mutex_);
      live_ = checks_.progress();
      live_at_ = now;
    }
    if (downstream_) downstream_(r);
  };
}

nlohmann::json RunVerdicts::finish(bool pressure_trip, const RunChecks::OtherRun& other) {
  if (!active_) return nullptr;
  summary_ = metrics_.finish();
  if (!knows_truth_) {  // no valve angle: a stall cannot be seen
    constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
    summary_.stall_s_total = summary_.stall_fraction = kNaN;
    for (auto& r : summary_.reversals) r.stall_s = kNaN;
  }
  std::vector<CheckResult> results = checks_.finish(summary_, pressure_trip ? 1 : 0, other);
  if (rows_ == 0) {
    for (auto& r : results) {  // an IAE of 0 over no period passes nothing
      r.verdict = Verdict::skipped;
      r.value = std::numeric_limits<double>::quiet_NaN();
      r.message = "the run recorded no period";
    }
  }
  return checks_json(results);
}

nlohmann::json RunVerdicts::live() const {
  if (!active_) return nullptr;
  RunChecks::Progress p;
  {
    std::lock_guard lock(live_mutex_);
    p = live_;
  }
  nlohmann::json results = nlohmann::json::array();
  for (const LiveCheck& c : checks_.live(p)) results.push_back(c.to_json());
  return {{"run", checks_.run()}, {"t_s", p.rows > 0 ? nlohmann::json(p.t_s) : nlohmann::json(nullptr)}, {"results", results}};
}

}  // namespace hil::bench
