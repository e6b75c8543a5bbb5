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

#include "hil/bench/campaign.hpp"
#include "hil/bench/run_metrics.hpp"
#include "hil/csv_writer.hpp"
#include "hil/telemetry_schema.hpp"

namespace hil::bench {

// hilbench sim's telemetry columns: the first telemetry::kSimColumns of the one schema
// (hil/telemetry_schema.hpp), in its order; telemetry_row fills them from a step.
inline constexpr std::size_t kSimColumns = telemetry::kSimColumns;
const std::vector<CsvColumn>& sim_telemetry_columns();
std::array<double, kSimColumns> telemetry_row(const StepRecord& r);
// Every column of the schema for one period: the above, then what the drive was sent
// (theta_target_rad; NaN: the command) and the bench loop's timing and flags.
std::array<double, telemetry::kLoopColumns> full_telemetry_row(const StepRecord& r, double theta_target_rad,
                                                              double wake_latency_us = 0, double compute_us = 0,
                                                              std::uint32_t loop_flags = 0);

// Runs one campaign run; calls on_step(const StepRecord&) every control period. Counts finished
// steps into steps_done (relaxed, every 1024 steps) when given.
template <class OnStep>
void simulate_run(const Campaign& c, const RunSpec& run, OnStep&& on_step, std::atomic<long>* steps_done = nullptr) {
  const plant::Plant& plant = *c.plant;
  plant::PlantState ps = plant.make_state(c.seed);
  Schedule::Cursor ref_cursor, gap_cursor;
  const double gap0 = c.gap_rad.at(0.0, gap_cursor);
  plant.settle(ps, c.reference_pa.at(0.0, ref_cursor), plant::kNaN, 0.0, gap0);
  const ctl::Controller controller(run.controller);
  ctl::ControllerState cs = controller.initial_state(ps.s.theta_cmd_rad, ps.s.p_meas_pa, run.initial_touch);
  const long n = std::lround(c.duration_s / c.period_s);
  for (long k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) * c.period_s;
    const double p_ref = c.reference_pa.at(t, ref_cursor);
    const double gap = c.gap_rad.at(t, gap_cursor);
    const ctl::ControllerOutputs out = controller.step(cs, {ps.s.p_meas_pa, p_ref, ps.s.theta_motor_rad});
    StepRecord r;
    r.t_s = t;
    r.p_ref_pa = p_ref;
    r.p_chamber_pa = ps.s.p_chamber_pa;
    r.p_meas_pa = ps.s.p_meas_pa;
    r.theta_cmd_rad = out.theta_cmd_rad;
    r.theta_motor_rad = ps.s.theta_motor_rad;
    r.theta_valve_rad = ps.s.theta_valve_rad;
    r.gap_true_rad = gap;
    r.gap_est_rad = out.gap_est_rad;
    r.comp_rad = out.comp_rad;
    r.touch = out.touch_state;
    r.intention = out.motion_intention;
    r.gap_measured = out.gap_measured;
    on_step(r);
    plant.step(ps, {out.theta_cmd_rad, plant::kNaN, gap}, c.period_s);
    if (steps_done != nullptr && (k & 1023) == 1023) steps_done->fetch_add(1024, std::memory_order_relaxed);
  }
}

// The reversal metrics of a run without writing anything (tests, benchmarks, the README table).
RunSummary summarise_run(const Campaign& c, const RunSpec& run);

// A series kept for the report: at most ~2 points per bucket (the bucket's min and max, in time
// order), so an hour at 1 kHz stays a few thousand points with every spike kept.
struct ReportSeries {
  std::string name;
  std::vector<double> t_s, value;
};

struct RunOutcome {
  std::string name;
  RunSummary summary;
  std::vector<ReportSeries> series;  // p_ref, p_meas, touch, motor, valve, cmd, gap_est, gap_true, target
  double wall_s = 0;
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
  // theta_target_rad: what a rig's drive was sent (shaped), when it differs from the command.
  void add(const StepRecord& r, double theta_target_rad = plant::kNaN);
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
  double simulated_s = 0;     // summed over runs
};

// Throws std::runtime_error on I/O failure (the campaign folder is then left as it was).
CampaignOutcome run_campaign(const Campaign& c, const SimOptions& options);

}  // namespace hil::bench
