// What a run achieved, accumulated step by step: pressure tracking (IAE), the valve's stall at
// each reference reversal (seconds the valve stood still while the motor moved: simulation
// only, since the valve angle is not measured on a rig), the gap estimate against the true gap
// at each reversal, and the observer's activity. add() is allocation-free.
#pragma once

#include <cstddef>
#include <vector>

#include <nlohmann/json.hpp>

#include "hil/bench/rt/telemetry_record.hpp"  // StepRecord

namespace hil::bench {

struct ReversalSummary {
  double t_s = 0;
  double stall_s = 0;      // valve still while the motor moved, until the next reversal
  double gap_est_deg = 0;  // the estimate the compensator held when the reversal began
  double gap_true_deg = 0;
  double iae_mpa_s = 0;
  int touch_state_changes = 0;
};

struct RunSummary {
  double duration_s = 0;
  double iae_mpa_s = 0;  // integral of |Pg - Pref| (true chamber pressure)
  double rmse_mpa = 0;
  double stall_s_total = 0;
  double stall_fraction = 0;  // stall time / time the motor moved
  double gap_est_final_deg = 0;
  double gap_true_final_deg = 0;
  long touch_state_changes = 0;
  long compensation_events = 0;
  long gap_measurements = 0;
  long reference_changes = 0;  // moves of the reference (steps, ramps), in either direction
  std::vector<ReversalSummary> reversals;
  nlohmann::json to_json() const;
};

class RunMetrics {
 public:
  // Motor "moves" when faster than motion_threshold_rad_s (noise makes it creep).
  RunMetrics(std::vector<double> reversals_s, long reference_changes, double period_s, double motion_threshold_rad_s);
  void add(const StepRecord& r) noexcept;
  RunSummary finish() const;

 private:
  double period_s_, motion_step_rad_;
  RunSummary sum_;
  std::size_t next_reversal_ = 0;
  bool have_prev_ = false;
  StepRecord prev_;
  double sq_error_ = 0, motor_moving_s_ = 0;
  long steps_ = 0;
};

}  // namespace hil::bench
