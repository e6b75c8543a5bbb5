// The paper's integral pressure controller with backlash compensation:
//   theta_c(k) = theta_c(k-1) + KI(Pg0, V0) * dT * dPg + delta_b,   dPg = Pg_meas - Pg_ref
// KI is scheduled on the reference pressure and the estimated free volume (physics.md s.2):
//   KI = 1 / (4 zeta^2 tau |kp|). delta_b is the compensation jump at a reversal: none (the
// paper's original method), constant (known sigma) or adaptive (learned sigma_r).
//   paper observer:  eq. (7), +-sigma when the touch state leaves a flank.
//   robust observer: the controller keeps where the motor sits in the gap, a play operator of
//     the commands with the estimated gap (gap_pos in [-sigma/2, +sigma/2], +sigma/2 = resting
//     on the flank that opens the valve). At each motion reversal the command jumps by exactly
//     the distance to the flank ahead; reversals inside the gap jump only what is left. While
//     the motor crosses the gap the jump is enlarged by traverse_boost (a fraction of it), and
//     the extra is taken back one step before the motor (encoder or model) reaches the flank: the
//     drive then crosses at its slew limit instead of creeping along its lag's exponential tail.
//     The jump aims contact_overlap_rad past the flank, so contact is made while the motor still
//     moves (the motion the reversal asked for absorbs that much).
// step() is real-time safe: noexcept, no allocation, no locking, no I/O.
#pragma once

#include <limits>
#include <stdexcept>

#include "hil/ctl/chamber_model.hpp"
#include "hil/ctl/observer.hpp"
#include "hil/units.hpp"

namespace hil::ctl {

enum class Compensation { none, constant, adaptive };
enum class ObserverKind { paper, robust };

// The drive as the controller designer models it; used when no encoder angle is available.
struct MotorModel {
  double time_constant_s = 0.010;
  double rate_limit_rad_s = units::deg_to_rad(60);
};

struct ControllerParams {
  double period_s = 1e-3;
  Compensation compensation = Compensation::adaptive;
  ObserverKind observer = ObserverKind::robust;
  double gap_known_rad = 0;                              // constant mode: the known sigma
  double gap_initial_rad = 0;                            // adaptive mode: sigma_r(0)
  double damping_ratio = 0.7;                            // zeta of the KI schedule
  double traverse_boost = 1.0;                           // robust: extra command while crossing the gap, x the jump
  double contact_overlap_rad = units::deg_to_rad(0.02);  // robust: jump this far past the flank
  double cmd_min_rad = -0.0873;                          // command limits (the valve travel plus the largest gap)
  double cmd_max_rad = 0.6109;
  bool use_encoder = true;  // motor angle from the drive; otherwise from `motor`
  double volume_initial_m3 = 2e-3;
  ChamberModel chamber;
  MotorModel motor;
  RobustObserverParams robust;
  void validate() const;  // throws std::invalid_argument naming the parameter
};

struct ControllerInputs {
  double p_meas_pa = 0;
  double p_ref_pa = 0;
  double theta_motor_rad = std::numeric_limits<double>::quiet_NaN();  // NaN: no encoder
};

struct ControllerOutputs {
  double theta_cmd_rad = 0;  // what goes to the drive (includes a traverse boost)
  double comp_rad = 0;       // delta_b applied this step
  int touch_state = 0;
  int motion_intention = 0;
  double gap_est_rad = 0;  // sigma (constant) or sigma_r (adaptive; observe-only with none)
  double ki_rad_per_pa_s = 0;
  bool gap_measured = false;  // the robust observer completed a gap measurement this step
};

struct ControllerState {
  double theta_cmd_rad = 0;
  double gap_est_rad = 0;
  double volume_m3 = 0;        // integrated from the nominal burn rate and the measured pressure
  double volume_p_sum_pa = 0;  // pressures since the last volume update (every kVolumeSteps)
  int volume_steps = 0;
  double sched_p_ref_pa = -1;     // the reference the schedule below was computed for
  double sched_tau_s_per_m3 = 0;  // tau / V at that reference (tau is proportional to V)
  double sched_ki_m3 = 0;         // KI * V at that reference
  double motor_model_rad = 0;
  double gap_pos_rad = 0;  // robust: believed motor position in the gap
  double boost_rad = 0;    // robust: extra command while the motor crosses the gap
  long presume_wait = 0;   // robust: steps before the play model's flank may be trusted
  int gap_measurements = 0;
  PaperObserverState paper;
  RobustObserverState robust;
};

class Controller {
 public:
  explicit Controller(const ControllerParams& params);
  // touch: which flank the motor is believed to rest on at start (0 = unknown).
  ControllerState initial_state(double theta_cmd_rad, double p_meas_pa, int touch) const noexcept;
  ControllerOutputs step(ControllerState& s, const ControllerInputs& in) const noexcept {
    ControllerOutputs out;
    step(s, in, out);
    return out;
  }
  // The same, writing into `out`: a caller that keeps the outputs (the run loop) reads them field
  // by field where step() stored them, instead of copying the whole struct right after the stores
  // (a wide load over several narrow stores cannot be forwarded and stalls the period).
  void step(ControllerState& s, const ControllerInputs& in, ControllerOutputs& out) const noexcept;
  double ki_rad_per_pa_s(double p0_pa, double volume_m3) const noexcept;
  const ControllerParams& params() const noexcept { return p_; }
  const RobustObserver& robust_observer() const noexcept { return robust_; }

 private:
  ControllerParams p_;
  PaperObserver paper_;
  RobustObserver robust_;
  double motor_keep_ = 0;                  // exp(-dT / tau_m) of the motor model
  static constexpr int kVolumeSteps = 10;  // the volume grows slowly: integrate it every 10 steps
};

}  // namespace hil::ctl
