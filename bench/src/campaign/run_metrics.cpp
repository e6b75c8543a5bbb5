#include "hil/bench/campaign/run_metrics.hpp"

#include <cmath>

#include "hil/units.hpp"

namespace hil::bench {

using units::pa_to_mpa;
using units::rad_to_deg;

RunMetrics::RunMetrics(std::vector<double> reversals_s, long reference_changes, double period_s, double motion_threshold_rad_s)
    : period_s_(period_s), motion_step_rad_(motion_threshold_rad_s * period_s) {
  sum_.reference_changes = reference_changes;
  sum_.reversals.reserve(reversals_s.size());
  for (double t : reversals_s) sum_.reversals.push_back({t});
}

void RunMetrics::add(const StepRecord& r) noexcept {
  const double err_mpa = pa_to_mpa(r.p_chamber_pa - r.p_ref_pa);
  sum_.iae_mpa_s += std::abs(err_mpa) * period_s_;
  sq_error_ += err_mpa * err_mpa;
  ++steps_;
  // Enter the window of a reversal: note what the compensator held just before it.
  while (next_reversal_ < sum_.reversals.size() && r.t_s >= sum_.reversals[next_reversal_].t_s - 1e-9) {
    const StepRecord& before = have_prev_ ? prev_ : r;
    sum_.reversals[next_reversal_].gap_est_deg = rad_to_deg(before.gap_est_rad);
    sum_.reversals[next_reversal_].gap_true_deg = rad_to_deg(r.gap_true_rad);
    ++next_reversal_;
  }
  ReversalSummary* window = next_reversal_ > 0 ? &sum_.reversals[next_reversal_ - 1] : nullptr;
  if (window) window->iae_mpa_s += std::abs(err_mpa) * period_s_;
  if (have_prev_) {
    const bool motor_moved = std::abs(r.theta_motor_rad - prev_.theta_motor_rad) > motion_step_rad_;
    const bool valve_still = std::abs(r.theta_valve_rad - prev_.theta_valve_rad) < 1e-12;
    if (motor_moved) motor_moving_s_ += period_s_;
    if (motor_moved && valve_still) {
      sum_.stall_s_total += period_s_;
      if (window) window->stall_s += period_s_;
    }
    if (r.touch != prev_.touch) {
      ++sum_.touch_state_changes;
      if (window) ++window->touch_state_changes;
    }
  }
  if (r.comp_rad != 0) ++sum_.compensation_events;
  if (r.gap_measured) ++sum_.gap_measurements;
  sum_.gap_est_final_deg = rad_to_deg(r.gap_est_rad);
  sum_.gap_true_final_deg = rad_to_deg(r.gap_true_rad);
  sum_.duration_s = r.t_s + period_s_;
  prev_ = r;
  have_prev_ = true;
}

RunSummary RunMetrics::finish() const {
  RunSummary out = sum_;
  out.reversals.resize(next_reversal_);  // reversals after the end of the run never happened
  out.rmse_mpa = steps_ ? std::sqrt(sq_error_ / static_cast<double>(steps_)) : 0;
  out.stall_fraction = motor_moving_s_ > 0 ? out.stall_s_total / motor_moving_s_ : 0;
  return out;
}

nlohmann::json RunSummary::to_json() const {
  nlohmann::json stall = nlohmann::json::array(), rev = nlohmann::json::array();
  for (const auto& r : reversals) {
    stall.push_back(r.stall_s);
    rev.push_back({{"t_s", r.t_s},
                   {"stall_s", r.stall_s},
                   {"gap_est_deg", r.gap_est_deg},
                   {"gap_true_deg", r.gap_true_deg},
                   {"iae_mpa_s", r.iae_mpa_s},
                   {"touch_state_changes", r.touch_state_changes}});
  }
  return {
      {"duration_s", duration_s},
      {"iae_mpa_s", iae_mpa_s},
      {"rmse_mpa", rmse_mpa},
      {"stall_s_per_reversal", stall},
      {"stall_s_total", stall_s_total},
      {"stall_fraction_of_motion", stall_fraction},
      {"gap_est_final_deg", gap_est_final_deg},
      {"gap_true_final_deg", gap_true_final_deg},
      {"touch_state_changes", touch_state_changes},
      {"touch_state_changes_per_reversal", reversals.empty() ? 0.0 : static_cast<double>(touch_state_changes) / reversals.size()},
      {"touch_state_changes_per_reference_change",
       reference_changes == 0 ? 0.0 : static_cast<double>(touch_state_changes) / reference_changes},
      {"reference_changes", reference_changes},
      {"compensation_events", compensation_events},
      {"gap_measurements", gap_measurements},
      {"reversals", rev}};
}

}  // namespace hil::bench
