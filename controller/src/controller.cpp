#include "hil/ctl/controller.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "hil/physics.hpp"

namespace hil::ctl {

void ControllerParams::validate() const {
  auto check = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("controller: ") + what);
  };
  check(period_s > 0, "period must be > 0");
  check(gap_known_rad >= 0, "known gap must be >= 0");
  check(gap_initial_rad >= 0, "initial gap estimate must be >= 0");
  check(damping_ratio > 0, "damping ratio must be > 0");
  check(traverse_boost >= 0 && traverse_boost <= 5, "traverse boost must be in [0, 5]");
  check(contact_overlap_rad >= 0, "contact overlap must be >= 0");
  check(cmd_min_rad < cmd_max_rad, "command limits must have min < max");
  check(volume_initial_m3 > 0, "initial volume must be > 0");
  check(motor.time_constant_s > 0 && motor.rate_limit_rad_s > 0, "motor model needs positive lag and rate limit");
  chamber.validate();
  robust.validate();
}

namespace {
ControllerParams validated(ControllerParams p) {
  p.robust.period_s = p.period_s;
  p.validate();
  return p;
}
}  // namespace

Controller::Controller(const ControllerParams& params)
    : p_(validated(params)),
      robust_(p_.robust, p_.chamber),
      motor_keep_(physics::servo_keep(p_.period_s, p_.motor.time_constant_s)) {}

ControllerState Controller::initial_state(double theta_cmd_rad, double p_meas_pa, int touch) const noexcept {
  ControllerState s;
  s.theta_cmd_rad = theta_cmd_rad;
  s.gap_est_rad = p_.compensation == Compensation::constant ? p_.gap_known_rad : p_.gap_initial_rad;
  s.volume_m3 = p_.volume_initial_m3;
  s.motor_model_rad = theta_cmd_rad;
  s.gap_pos_rad = touch * s.gap_est_rad / 2;
  s.paper = paper_.initial_state(touch, p_meas_pa);
  s.robust = robust_.initial_state(touch, theta_cmd_rad, p_meas_pa, theta_cmd_rad);
  return s;
}

double Controller::ki_rad_per_pa_s(double p0_pa, double volume_m3) const noexcept {
  const double tau = p_.chamber.time_constant_s(p0_pa, volume_m3);
  const double kp = p_.chamber.gain_pa_per_rad(p0_pa);
  return 1.0 / (4 * p_.damping_ratio * p_.damping_ratio * tau * kp);
}

void Controller::step(ControllerState& s, const ControllerInputs& in, ControllerOutputs& out) const noexcept {
  out = ControllerOutputs{};
  // The KI(Pg0, V0) schedule: at a given reference tau is proportional to V and KI to 1/V, so
  // the expensive part is computed once per reference value.
  if (in.p_ref_pa != s.sched_p_ref_pa) {
    s.sched_p_ref_pa = in.p_ref_pa;
    s.sched_tau_s_per_m3 = p_.chamber.time_constant_s(in.p_ref_pa, 1.0);
    s.sched_ki_m3 = ki_rad_per_pa_s(in.p_ref_pa, 1.0);
  }
  const double tau_s = s.sched_tau_s_per_m3 * s.volume_m3;
  out.ki_rad_per_pa_s = s.sched_ki_m3 / s.volume_m3;
  // Pressure too high -> open the valve: the stabilising sign of eq. (5).
  double cmd_step = out.ki_rad_per_pa_s * p_.period_s * (in.p_meas_pa - in.p_ref_pa);
  const double motor_rad = p_.use_encoder && std::isfinite(in.theta_motor_rad) ? in.theta_motor_rad : s.motor_model_rad;

  // The play model presumes the motor pushed a flank when it sits within the intention's
  // dead-band of it (a reversal is only seen after that retreat); with no gap known, or while a
  // jump may still be under way in the drive, nothing.
  const double gap_before = p_.compensation == Compensation::constant ? p_.gap_known_rad : s.gap_est_rad;
  const bool gap_known = p_.compensation == Compensation::constant || s.gap_measurements > 0;
  const double near = gap_before / 2 - p_.robust.intention_deadband_rad - 1e-12;
  if (s.presume_wait > 0) --s.presume_wait;
  const int presumed = !gap_known || s.presume_wait > 0 ? 0 : s.gap_pos_rad >= near ? 1 : s.gap_pos_rad <= -near ? -1 : 0;
  const ObserverInputs obs_in{cmd_step, in.p_meas_pa - in.p_ref_pa, in.p_meas_pa, motor_rad, tau_s, s.volume_m3, presumed};
  const ObserverOutputs obs = p_.observer == ObserverKind::paper ? paper_.step(s.paper, obs_in) : robust_.step(s.robust, obs_in);

  // The estimate: law (10) for the paper observer, measured gaps for the robust one. With
  // compensation `none` it is still learned (observe only) so telemetry shows what it would do.
  if (p_.compensation != Compensation::constant) {
    if (p_.observer == ObserverKind::paper) {
      s.gap_est_rad += obs.transition_travel_rad;
    } else if (obs.gap_measured) {
      // The first measurement, and one showing a real change, replace the estimate; the others
      // move it part way (averaging the measurement noise).
      const double innovation = obs.gap_measured_rad - s.gap_est_rad;
      const bool jump = std::abs(innovation) > p_.robust.jump_fraction * s.gap_est_rad;
      const double gain = s.gap_measurements++ == 0 || jump ? 1.0 : p_.robust.learn_gain;
      const double before = s.gap_est_rad;
      s.gap_est_rad += gain * innovation;
      // Where the motor sits in the gap, in the new gap: on a flank it stays on that flank.
      if (before > 0) s.gap_pos_rad *= s.gap_est_rad / before;
    }
  }
  if (p_.observer == ObserverKind::paper) {
    // Eq. (7) with sigma (constant) or sigma_r (adaptive) as it was before this step's law (10).
    if (p_.compensation != Compensation::none) out.comp_rad = obs.kick * gap_before;
  } else {
    const double gap = p_.compensation == Compensation::constant ? p_.gap_known_rad : s.gap_est_rad;  // as updated
    s.gap_pos_rad += cmd_step;
    if (obs.reversed) s.boost_rad = 0;
    if (p_.compensation != Compensation::none && obs.reversed) {
      const int d = obs.intention;
      out.comp_rad = d * (std::max(gap / 2 - d * s.gap_pos_rad, 0.0) + p_.contact_overlap_rad);  // past the flank ahead
      s.gap_pos_rad += out.comp_rad;
      s.boost_rad = p_.traverse_boost * out.comp_rad;
      // The drive needs the crossing at its slew limit plus a few lags to really get there.
      s.presume_wait =
          std::lround((std::abs(out.comp_rad) / p_.motor.rate_limit_rad_s + 3 * p_.motor.time_constant_s) / p_.period_s);
    }
    s.gap_pos_rad = std::clamp(s.gap_pos_rad, -gap / 2, gap / 2);  // at a flank: pushing the valve
  }
  s.theta_cmd_rad = std::clamp(s.theta_cmd_rad + cmd_step + out.comp_rad, p_.cmd_min_rad, p_.cmd_max_rad);
  // Take the boost back when the motor will reach the jump's target within this step.
  const double step_reach = p_.motor.rate_limit_rad_s * p_.period_s;
  if (s.boost_rad > 0 ? motor_rad + step_reach >= s.theta_cmd_rad : motor_rad - step_reach <= s.theta_cmd_rad) s.boost_rad = 0;
  const double cmd = std::clamp(s.theta_cmd_rad + s.boost_rad, p_.cmd_min_rad, p_.cmd_max_rad);
  // The motor model predicts the drive's angle at the next sample (lag, then rate limit).
  s.motor_model_rad = physics::servo_step_rad(s.motor_model_rad, cmd, motor_keep_, p_.motor.rate_limit_rad_s * p_.period_s);
  s.volume_p_sum_pa += in.p_meas_pa;
  if (++s.volume_steps == kVolumeSteps) {
    s.volume_m3 += p_.chamber.volume_rate_m3_s(s.volume_p_sum_pa / kVolumeSteps) * kVolumeSteps * p_.period_s;
    s.volume_p_sum_pa = 0;
    s.volume_steps = 0;
  }

  out.theta_cmd_rad = cmd;
  out.touch_state = obs.touch;
  out.motion_intention = obs.intention;
  out.gap_est_rad = s.gap_est_rad;
  out.gap_measured = obs.gap_measured;
}

}  // namespace hil::ctl
