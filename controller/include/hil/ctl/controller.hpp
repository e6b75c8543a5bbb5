// The paper's integral pressure controller with backlash compensation:
//   theta_c(k) = theta_c(k-1) + KI(Pg0, V0) * dT * dPg + delta_b,   dPg = Pg_meas - Pg_ref
// KI is scheduled on the reference pressure and the estimated free volume (physics.md s.2):
//   KI = 1 / (4 zeta^2 tau |kp|). delta_b is the compensation jump at a reversal, decided by a
// registered compensator (compensator.hpp: an observer and its law; `robust` and `paper` are
// shipped), applied as none (the paper's original method), constant (known sigma) or adaptive
// (learned sigma_r). While the motor crosses the gap after a jump the command is enlarged by
// traverse_boost (a fraction of the jump), and the extra is taken back one step before the
// motor (encoder or model) reaches the jump's target: the drive then crosses at its slew limit
// instead of creeping along its lag's exponential tail.
// step() is real-time safe: noexcept, no allocation, no locking, no I/O.
#pragma once

#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "hil/ctl/chamber_model.hpp"
#include "hil/ctl/compensator.hpp"
#include "hil/units.hpp"

namespace hil::ctl {

struct ControllerParams {
  double period_s = 1e-3;
  Compensation compensation = Compensation::adaptive;
  std::string compensator = "robust";      // a registered compensator (compensator.hpp)
  std::vector<double> compensator_params;  // its parameters, its specs' order and units; empty: the defaults
  double gap_known_rad = 0;                // constant mode: the known sigma
  double gap_initial_rad = 0;              // adaptive mode: sigma_r(0)
  double damping_ratio = 0.7;              // zeta of the KI schedule
  double traverse_boost = 1.0;             // extra command while crossing the gap, x the jump
  double cmd_min_rad = -0.0873;            // command limits (the valve travel plus the largest gap)
  double cmd_max_rad = 0.6109;
  bool use_encoder = true;  // motor angle from the drive; otherwise from `motor`
  double volume_initial_m3 = 2e-3;
  ChamberModel chamber;
  MotorModel motor;
  // Throws std::invalid_argument naming the parameter (the compensator's too: it is built).
  void validate() const;
  CompensatorSetup compensator_setup() const;  // what the compensator is told
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
  bool gap_measured = false;  // the compensator completed a gap measurement this step
};

// The compensator's state in a controller state: a copy clones it (setup time; the period never
// copies a state).
class CompensatorStateBox {
 public:
  CompensatorStateBox() = default;
  explicit CompensatorStateBox(std::unique_ptr<CompensatorState> state) : p_(std::move(state)) {}
  CompensatorStateBox(const CompensatorStateBox& o) : p_(o.p_ ? o.p_->clone() : nullptr) {}
  CompensatorStateBox& operator=(const CompensatorStateBox& o) {
    if (this != &o) p_ = o.p_ ? o.p_->clone() : nullptr;
    return *this;
  }
  CompensatorStateBox(CompensatorStateBox&&) noexcept = default;
  CompensatorStateBox& operator=(CompensatorStateBox&&) noexcept = default;
  CompensatorState* get() const noexcept { return p_.get(); }

 private:
  std::unique_ptr<CompensatorState> p_;
};

struct ControllerState {
  double theta_cmd_rad = 0;
  double volume_m3 = 0;        // integrated from the nominal burn rate and the measured pressure
  double volume_p_sum_pa = 0;  // pressures since the last volume update (every kVolumeSteps)
  int volume_steps = 0;
  double sched_p_ref_pa = -1;     // the reference the schedule below was computed for
  double sched_tau_s_per_m3 = 0;  // tau / V at that reference (tau is proportional to V)
  double sched_ki_m3 = 0;         // KI * V at that reference
  double motor_model_rad = 0;
  double boost_rad = 0;  // extra command while the motor crosses the gap
  CompensatorStateBox compensator;
};

class Controller {
 public:
  explicit Controller(const ControllerParams& params);
  // touch: which flank the motor is believed to rest on at start (0 = unknown). Setup time (the
  // compensator's state is allocated here).
  ControllerState initial_state(double theta_cmd_rad, double p_meas_pa, int touch) const;
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
  const Compensator& compensator() const noexcept { return *compensator_; }

 private:
  ControllerParams p_;
  std::shared_ptr<const Compensator> compensator_;
  double motor_keep_ = 0;                  // exp(-dT / tau_m) of the motor model
  static constexpr int kVolumeSteps = 10;  // the volume grows slowly: integrate it every 10 steps
};

}  // namespace hil::ctl
