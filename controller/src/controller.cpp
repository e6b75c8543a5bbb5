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
  check(cmd_min_rad < cmd_max_rad, "command limits must have min < max");
  check(volume_initial_m3 > 0, "initial volume must be > 0");
  check(motor.time_constant_s > 0 && motor.rate_limit_rad_s > 0, "motor model needs positive lag and rate limit");
  chamber.validate();
  make_compensator(compensator, compensator_setup(), compensator_params);  // checks its parameters
}

CompensatorSetup ControllerParams::compensator_setup() const {
  return {period_s, compensation, gap_known_rad, gap_initial_rad, chamber, motor};
}

namespace {
const ControllerParams& validated(const ControllerParams& p) {
  p.validate();
  return p;
}
}  // namespace

Controller::Controller(const ControllerParams& params)
    : p_(validated(params)),
      compensator_(make_compensator(p_.compensator, p_.compensator_setup(), p_.compensator_params)),
      motor_keep_(physics::servo_keep(p_.period_s, p_.motor.time_constant_s)) {}

ControllerState Controller::initial_state(double theta_cmd_rad, double p_meas_pa, int touch) const {
  ControllerState s;
  s.theta_cmd_rad = theta_cmd_rad;
  s.volume_m3 = p_.volume_initial_m3;
  s.motor_model_rad = theta_cmd_rad;
  s.compensator = CompensatorStateBox(compensator_->initial_state(theta_cmd_rad, p_meas_pa, touch));
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

  // The compensator: touch state, motion intention, the gap and the jump delta_b.
  CompensatorOutputs comp;
  if (CompensatorState* cs = s.compensator.get()) {
    compensator_->step(*cs, {cmd_step, in.p_meas_pa - in.p_ref_pa, in.p_meas_pa, motor_rad, tau_s, s.volume_m3}, comp);
  }
  out.comp_rad = comp.comp_rad;
  if (comp.reversed) s.boost_rad = p_.traverse_boost * comp.comp_rad;
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
  out.touch_state = comp.touch;
  out.motion_intention = comp.intention;
  out.gap_est_rad = comp.gap_est_rad;
  out.gap_measured = comp.gap_measured;
}

}  // namespace hil::ctl
