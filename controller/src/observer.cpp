#include "hil/ctl/observer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace hil::ctl {
namespace {
int sign(double v) noexcept { return (v > 0) - (v < 0); }
}  // namespace

// ----------------------------------------------------------------------------- paper, eq. (3)-(4)
ObserverOutputs PaperObserver::step(PaperObserverState& s, const ObserverInputs& in) const noexcept {
  ObserverOutputs out;
  out.intention = sign(in.cmd_step_rad);  // (3)
  const double dp = in.p_meas_pa - s.p_prev_pa;
  s.p_prev_pa = in.p_meas_pa;
  const int before = s.touch;
  if ((before == -1 && out.intention == +1) || (before == +1 && out.intention == -1)) {
    s.touch = 0;  // (4), first line
  } else if (before == 0 && dp > 0) {
    s.touch = -1;  // pressure up: valve being closed
  } else if (before == 0 && dp < 0) {
    s.touch = +1;  // pressure down: valve being opened
  }
  out.touch = s.touch;
  if (before != 0 && s.touch == 0) out.kick = -before;                              // (7): -sigma from +1, +sigma from -1
  out.transition_travel_rad = std::abs(in.cmd_step_rad) * (1 - std::abs(s.touch));  // (10)
  return out;
}

// ----------------------------------------------------------------------------- robust
void RobustObserverParams::validate() const {
  auto check = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("robust observer: ") + what);
  };
  check(period_s > 0, "period must be > 0");
  check(pressure_noise_rms_pa >= 0, "pressure_noise_rms must be >= 0");
  check(intention_deadband_rad >= 0, "intention_deadband must be >= 0");
  check(intention_sigmas >= 0, "intention_sigmas must be >= 0 (0 = off)");
  check(filter_time_constant_s > 0, "filter_time_constant must be > 0");
  check(hold_smoothing >= 1, "hold_smoothing must be >= 1");
  check(time_constant_scale > 0 && time_constant_scale <= 2, "time_constant_scale must be in (0, 2]");
  check(detect_sigmas > 0, "detect_sigmas must be > 0");
  check(confirm_samples >= 1, "confirm_samples must be >= 1");
  check(fit_lead_s >= 0, "fit_lead must be >= 0");
  check(fit_after_s > 0, "fit_after must be > 0");
  check(fit_tries >= 1, "fit_tries must be >= 1");
  check(learn_gain > 0 && learn_gain <= 1, "learn_gain must be in (0, 1]");
  check(jump_fraction > 0, "jump_fraction must be > 0");
  check(gap_max_rad > 0, "gap_max must be > 0");
}

namespace {
double stage_factor(const RobustObserverParams& p) { return 1 - std::exp(-p.period_s / p.filter_time_constant_s); }
const RobustObserverParams& checked(const RobustObserverParams& p) {
  p.validate();
  return p;
}
}  // namespace

RobustObserver::RobustObserver(const RobustObserverParams& params, const ChamberModel& chamber)
    : p_(checked(params)), chamber_(chamber), fit_(stage_factor(p_), p_.gap_max_rad) {
  chamber_.validate();
  area_solver_ = physics::ThroatAreaSolver(chamber_);
  inv_period_s_ = 1 / p_.period_s;
  alpha_ = stage_factor(p_);
  alpha_slow_ = 1 - std::exp(-p_.period_s / (p_.hold_smoothing * p_.filter_time_constant_s));
  lead_samples_ = std::lround(p_.fit_lead_s / p_.period_s);
  after_samples_ = std::max<std::int64_t>(1, std::lround(p_.fit_after_s / p_.period_s));
  skip_samples_ = std::lround(2 * p_.filter_time_constant_s / p_.period_s);
  // Noise gains: run unit impulses through both filter chains (long enough to decay fully).
  const int n = static_cast<int>(std::ceil(40 * p_.filter_time_constant_s / p_.period_s)) + 2;
  std::vector<double> hp(n), hd(n);
  double a1 = 0, a2 = 0, b1 = 0, b2 = 0, prev = 0;
  for (int k = 0; k < n; ++k) {
    const double x = k == 0 ? 1.0 : 0.0;
    a1 += alpha_ * (x - a1);
    a2 += alpha_ * (a1 - a2);
    b1 += alpha_ * ((x - prev) / p_.period_s - b1);
    b2 += alpha_ * (b1 - b2);
    prev = x;
    hp[k] = a2;
    hd[k] = b2;
  }
  // One low-pass stage on white noise keeps alpha / (2 - alpha) of its variance.
  error_sigma_gain_ = p_.intention_sigmas * std::sqrt(alpha_ / (2 - alpha_));
  error_threshold_pa_ = p_.intention_sigmas * p_.pressure_noise_rms_pa * std::sqrt(alpha_ / (2 - alpha_));
  for (int k = 0; k < n; ++k) {
    var_p_ += hp[k] * hp[k];
    var_pd_ += hp[k] * hd[k];
    var_d_ += hd[k] * hd[k];
  }
}

double RobustObserver::p_eq_noise_pa(double tau_s, double noise_rms_pa) const noexcept {
  const double t = tau_s * p_.time_constant_scale;
  return noise_rms_pa * std::sqrt(std::max(var_p_ + 2 * t * var_pd_ + t * t * var_d_, 0.0));
}

RobustObserverState RobustObserver::initial_state(int touch, double theta_cmd_rad, double p_meas_pa,
                                                  double theta_motor_rad) const noexcept {
  RobustObserverState s;
  s.int_cmd_rad = s.int_extreme_rad = theta_cmd_rad;
  s.intention = touch;
  s.p_prev_pa = s.p_lp1 = s.p_lp2 = p_meas_pa;
  s.p_eq_pa = s.p_eq_slow_pa = p_meas_pa;
  s.err_lp = 0;
  s.touch = touch;
  s.extreme_flank = touch;
  s.motor_extreme_valid = touch != 0;
  s.motor_extreme_rad = theta_motor_rad;
  return s;
}

ObserverOutputs RobustObserver::step(RobustObserverState& s, const ObserverInputs& in) const noexcept {
  ObserverOutputs out;
  // The noise this step is judged by: the caller's (online estimate) or the fixed assumption.
  const bool own_noise = in.noise_rms_pa >= 0;
  const double noise_rms_pa = own_noise ? in.noise_rms_pa : p_.pressure_noise_rms_pa;
  const double error_threshold_pa = own_noise ? error_sigma_gain_ * noise_rms_pa : error_threshold_pa_;
  // Filters: pressure and its derivative through the same two stages.
  const double dpdt = (in.p_meas_pa - s.p_prev_pa) * inv_period_s_;
  s.p_prev_pa = in.p_meas_pa;
  s.p_lp1 += alpha_ * (in.p_meas_pa - s.p_lp1);
  s.p_lp2 += alpha_ * (s.p_lp1 - s.p_lp2);
  s.d_lp1 += alpha_ * (dpdt - s.d_lp1);
  s.d_lp2 += alpha_ * (s.d_lp1 - s.d_lp2);
  s.err_lp += alpha_ * (in.error_pa - s.err_lp);
  const double tau = in.tau_s * p_.time_constant_scale;
  s.p_eq_pa = s.p_lp2 + tau * s.d_lp2;
  // The fit's valve angle: the chamber equation inverted for the throat area (no linearisation),
  // finished by fill_valve_eq when a fit needs it.
  s.discharge[GapFit::slot(s.history.count)] = chamber_.discharge(s.p_lp2, s.d_lp2, in.volume_m3, s.p_lp2_pow, area_solver_);
  GapFit::push(s.history, in.theta_motor_rad, std::numeric_limits<double>::quiet_NaN());
  const std::int64_t now = s.history.count - 1;
  s.p_eq_slow_pa += alpha_slow_ * (s.p_eq_pa - s.p_eq_slow_pa);

  // 1. Motion intention: the filtered error's direction with hysteresis, or a retreat of the
  //    integral command beyond the dead-band from its extreme.
  s.int_cmd_rad += in.cmd_step_rad;
  const double from_extreme = s.int_cmd_rad - s.int_extreme_rad;
  int wanted = 0;
  if (p_.intention_sigmas > 0 && std::abs(s.err_lp) > error_threshold_pa) wanted = sign(s.err_lp);
  if (std::abs(from_extreme) > p_.intention_deadband_rad && s.intention * from_extreme <= 0) wanted = sign(from_extreme);
  out.reversed = wanted != 0 && wanted != s.intention;
  if (out.reversed) {
    s.intention = wanted;
    s.int_extreme_rad = s.int_cmd_rad;
  } else if (s.intention * from_extreme > 0) {
    s.int_extreme_rad = s.int_cmd_rad;  // still moving the same way
  }
  out.intention = s.intention;

  // The motor's extreme on the flank that pushes the valve (confirmed, else presumed): with the
  // valve pushed, it fixes where that flank is.
  const int flank = s.touch != 0 ? s.touch : in.presumed_flank;
  if (flank != s.extreme_flank) {
    s.extreme_flank = flank;
    s.motor_extreme_valid = false;
  }
  if (flank != 0 && (!s.motor_extreme_valid || flank * (in.theta_motor_rad - s.motor_extreme_rad) > 0)) {
    s.motor_extreme_rad = in.theta_motor_rad;
    s.motor_extreme_at = now;
    s.motor_extreme_valid = true;
  }

  if (out.reversed) {
    // Reversing before a pending measurement: fit now with what the contact has shown so far.
    if (s.fit_at >= 0) measure(s, out);
    // Leave the flank: wait in transition for pressure evidence of the new one.
    s.transition_dir = s.intention;
    s.transition_extreme_valid = flank == -s.intention && s.motor_extreme_valid;
    s.transition_extreme_rad = s.motor_extreme_rad;
    s.transition_extreme_at = s.motor_extreme_at;
    s.hold_pa = s.p_eq_slow_pa;
    s.confirm = 0;
    s.touch = 0;
  } else if (s.touch == 0 && s.transition_dir != 0) {
    // 3. Exit from transition: P_eq has left the hold level toward the new side, beyond noise.
    // Opening (+1) lowers P_eq, so the old side is the high side: track its extreme.
    s.hold_pa = s.transition_dir > 0 ? std::max(s.hold_pa, s.p_eq_slow_pa) : std::min(s.hold_pa, s.p_eq_slow_pa);
    const double departure = s.transition_dir * (s.hold_pa - s.p_eq_pa);
    s.confirm = departure > p_.detect_sigmas * p_eq_noise_pa(in.tau_s, noise_rms_pa) ? s.confirm + 1 : 0;
    if (s.confirm >= p_.confirm_samples) {
      s.touch = s.transition_dir;
      if (s.transition_extreme_valid) {
        s.fit_at = now + after_samples_;
        s.fit_tries_left = p_.fit_tries;
      }
    }
  } else if (s.fit_at >= 0 && now >= s.fit_at) {
    measure(s, out);  // 4. the new flank has shown enough: fit the gap
  }
  out.touch = s.touch;
  return out;
}

void RobustObserver::fill_valve_eq(RobustObserverState& s) const noexcept {
  GapFit::History& h = s.history;
  for (std::int64_t i = std::max(s.valve_eq_known, h.count - GapFit::kMaxWindow); i < h.count; ++i) {
    const std::size_t at = GapFit::slot(i);
    h.valve_eq_rad[at] = chamber_.angle_for_area_rad(ChamberModel::throat_area_m2(s.discharge[at], area_solver_));
  }
  s.valve_eq_known = h.count;
}

void RobustObserver::measure(RobustObserverState& s, ObserverOutputs& out) const noexcept {
  const bool motion_goes_on = !out.reversed;
  s.fit_at = -1;
  fill_valve_eq(s);
  const GapFit::Result r =
      fit_.fit(s.history, s.transition_extreme_at, s.transition_extreme_rad, s.touch, lead_samples_, skip_samples_);
  if (!r.ok) {
    if (motion_goes_on && --s.fit_tries_left > 0) s.fit_at = s.history.count - 1 + after_samples_;  // look again later
    return;
  }
  out.gap_measured = true;
  out.gap_measured_rad = r.gap_rad;
}

}  // namespace hil::ctl
