// Touch-state observers: which flank of the gap drives the valve, from the command and the
// chamber pressure only (the valve angle is not measured). Two variants:
//   PaperObserver  - equations (3), (4) and (10) of the paper, exactly as written.
//   RobustObserver - this project's design for real sensors (see below).
// Both are pure step functions over explicit state: real-time safe (noexcept, no allocation,
// no locking, no I/O). Sign conventions: +1 = opening (valve angle up, pressure down).
#pragma once

#include <cstdint>

#include "hil/ctl/chamber_model.hpp"
#include "hil/ctl/gap_fit.hpp"
#include "hil/units.hpp"

namespace hil::ctl {

struct ObserverInputs {
  double cmd_step_rad;     // the integral controller's increment this step, KI*dT*dPg
  double error_pa;         // dPg = Pg_meas - Pg_ref: its sign is the command's direction
  double p_meas_pa;        // measured chamber pressure
  double theta_motor_rad;  // motor angle: encoder, or the controller's motor model
  double tau_s;            // nominal chamber time constant now (robust observer)
  double volume_m3;        // estimated free volume now (robust observer)
  int presumed_flank = 0;  // robust: the flank the controller's play model has the motor pushing
  // robust: the transducer noise (RMS) to judge this step by, e.g. estimated online by the
  // caller; negative: the params' pressure_noise_rms_pa (fixed at construction).
  double noise_rms_pa = -1;
};

struct ObserverOutputs {
  int touch = 0;                     // Tf: -1 negative touch, 0 transition, +1 positive touch
  int intention = 0;                 // Mf: -1, 0, +1
  int kick = 0;                      // paper: direction of the jump eq. (7) owes this step (touch -> transition)
  bool reversed = false;             // robust: the motion intention flipped this step
  double transition_travel_rad = 0;  // paper law (10): |KI dT dPg| while in transition
  bool gap_measured = false;         // robust: a gap measurement completed this step
  double gap_measured_rad = 0;
};

// ---------------------------------------------------------------------------------------------
// The paper's observer. Mf = sign(theta_c(k) - theta_c(k-1)); Tf from eq. (4) with strict signs
// of Pg(k) - Pg(k-1); the adaptive increment of eq. (10). Chatters under noise and chamber lag:
// kept to reproduce the paper and to show why the robust variant exists.
struct PaperObserverState {
  int touch = 0;
  double p_prev_pa = 0;
};

class PaperObserver {
 public:
  PaperObserverState initial_state(int touch, double p_meas_pa) const noexcept { return {touch, p_meas_pa}; }
  ObserverOutputs step(PaperObserverState& s, const ObserverInputs& in) const noexcept;
};

// ---------------------------------------------------------------------------------------------
// The robust observer. Four changes to the paper's method, each against one failure seen:
//
// 1. Motion intention with hysteresis: Mf flips when the low-passed pressure error says "move
//    the other way" by more than intention_sigmas standard deviations of its noise (the
//    integrator's velocity is KI*dPg, so this is its filtered direction), or, for reversals too
//    slow to show in the error, once the integral command has retreated intention_deadband_rad
//    from its extreme. Noise walking the integrator near a setpoint is not a reversal; a real
//    reversal is seen within a few milliseconds. The compensation jump is owed at each flip,
//    whatever the touch state (the controller keeps where the motor sits in the gap, see
//    controller.hpp): after a well-sized jump the valve may move too little for any pressure
//    evidence, and the next reversal must still be compensated.
// 2. The valve's motion is judged from the equilibrium pressure, not from Pg's slope:
//       P_eq = LP(Pg) + tau * LP(dPg/dt)
//    For the first-order chamber, P_eq is the pressure the current valve angle would hold, so it
//    stands still while the valve stands still, even while Pg still relaxes the old way after a
//    reversal (chamber lag, tau ~ 0.1 s). LP is two first-order stages of
//    filter_time_constant_s; tau is the scheduled nominal time constant times
//    time_constant_scale (< 1: an underestimated tau lets P_eq creep on the old side, where it
//    is harmless; an overestimate would creep toward the new side and fake an exit).
// 3. A noise-aware, direction-consistent exit from transition: the hold level is the extreme
//    reached on the old side since the reversal by P_eq smoothed once more (hold_smoothing
//    filter time constants; the running extreme of a noisy signal would drift outward with the
//    noise and fake an exit during a long hold); the observer returns to touch only after
//    P_eq has left it toward the new side by more than detect_sigmas standard deviations of
//    P_eq's noise (computed from the transducer noise and the filters) for confirm_samples in a
//    row. Noise alone does this about never, so Tf changes twice per real reversal.
// 4. The gap is measured, not accumulated: fit_after_s after the exit (or at the next reversal,
//    if sooner; and again every fit_after_s, up to fit_tries times, while the valve has not moved
//    enough to tell where contact was), GapFit finds the gap that best explains the recent history of the motor angle
//    and of the valve angle implied by the filtered pressure and its slope (the chamber equation
//    solved exactly for the throat area, then the map; see gap_fit.hpp), starting fit_lead_s
//    before the motor's extreme on the old flank. The motor must really have pushed the valve
//    there: confirmed by pressure, or presumed by the controller's play model of the gap (a
//    well-sized jump moves the valve too little for pressure to show). The estimate moves toward
//    each measurement by learn_gain, so it follows a gap that shrinks as well as one that grows
//    and averages the measurement noise; a measurement farther than jump_fraction from the
//    estimate is a real change and is taken whole (as is the first).
struct RobustObserverParams {
  double period_s = 1e-3;
  double pressure_noise_rms_pa = 2000;  // what the transducer's noise is believed to be
  double intention_deadband_rad = units::deg_to_rad(0.05);
  double intention_sigmas = 8;
  double filter_time_constant_s = 0.015;
  double hold_smoothing = 4;  // the hold level's extra low-pass, in filter time constants
  double time_constant_scale = 0.9;
  double detect_sigmas = 5;
  int confirm_samples = 5;
  double fit_lead_s = 0.02;
  double fit_after_s = 0.04;
  int fit_tries = 8;
  double learn_gain = 0.8;
  double jump_fraction = 0.2;
  double gap_max_rad = units::deg_to_rad(6);
  void validate() const;  // throws std::invalid_argument naming the parameter
};

struct RobustObserverState {
  // motion intention
  double int_cmd_rad = 0;      // the integral command, without compensation jumps
  double int_extreme_rad = 0;  // its extreme in the current direction of motion
  int intention = 0;
  // filters
  double p_prev_pa = 0;
  double p_lp1 = 0, p_lp2 = 0;  // pressure
  double d_lp1 = 0, d_lp2 = 0;  // pressure derivative, Pa/s
  double err_lp = 0;            // low-passed pressure error, Pa
  physics::PowNear p_lp2_pow;   // p_lp2^n for the chamber equation
  double p_eq_pa = 0;
  double p_eq_slow_pa = 0;  // P_eq smoothed further: the hold level tracks its extreme
  // touch state
  int touch = 0;
  int extreme_flank = 0;  // the flank whose motor extreme is being tracked
  bool motor_extreme_valid = false;
  double motor_extreme_rad = 0;       // extreme raw motor angle on the current flank
  std::int64_t motor_extreme_at = 0;  // its sample number
  int transition_dir = 0;
  double hold_pa = 0;                 // P_eq's extreme on the old side since the reversal
  double transition_extreme_rad = 0;  // motor extreme of the flank just left (for the measurement)
  std::int64_t transition_extreme_at = 0;
  bool transition_extreme_valid = false;
  int confirm = 0;
  // gap measurement after an exit
  std::int64_t fit_at = -1;  // sample number at which to fit; -1: none pending
  int fit_tries_left = 0;    // a slow contact may need a longer look before it shows enough
  GapFit::History history;
  // The fit's valve angle of each sample is the chamber equation inverted for the throat area,
  // then the map inverted: a division and a search. A fit reads a few hundred samples per
  // reversal, so the period keeps only the equation's discharge and a fit converts what it may
  // read (the last GapFit::kMaxWindow samples) first: the same angles, computed once each, for a
  // fraction of the samples.
  std::array<ChamberModel::Discharge, GapFit::kCapacity> discharge{};
  std::int64_t valve_eq_known = 0;  // history samples before this one have their valve angle
};

class RobustObserver {
 public:
  RobustObserver(const RobustObserverParams& params, const ChamberModel& chamber);
  RobustObserverState initial_state(int touch, double theta_cmd_rad, double p_meas_pa, double theta_motor_rad) const noexcept;
  ObserverOutputs step(RobustObserverState& s, const ObserverInputs& in) const noexcept;
  // Standard deviation of P_eq caused by the transducer noise, for a given tau.
  double p_eq_noise_pa(double tau_s) const noexcept { return p_eq_noise_pa(tau_s, p_.pressure_noise_rms_pa); }
  double p_eq_noise_pa(double tau_s, double noise_rms_pa) const noexcept;
  // Hysteresis of the motion intention on the low-passed pressure error.
  double intention_threshold_pa() const noexcept { return error_threshold_pa_; }
  const RobustObserverParams& params() const noexcept { return p_; }

 private:
  RobustObserverParams p_;
  ChamberModel chamber_;
  physics::ThroatAreaSolver area_solver_;      // chamber_'s equation solved for the throat area
  double inv_period_s_ = 0;                    // 1 / period: the derivative multiplies, off the division
  double alpha_ = 0;                           // per-step factor of each low-pass stage
  double alpha_slow_ = 0;                      // per-step factor of the hold level's extra smoothing
  double var_p_ = 0, var_pd_ = 0, var_d_ = 0;  // noise gains of LP(p), cross, LP(dp/dt)
  double error_threshold_pa_ = 0;
  double error_sigma_gain_ = 0;  // the error threshold per Pa of transducer noise
  GapFit fit_;
  std::int64_t lead_samples_ = 0, after_samples_ = 0, skip_samples_ = 0;
  void measure(RobustObserverState& s, ObserverOutputs& out) const noexcept;
  void fill_valve_eq(RobustObserverState& s) const noexcept;  // the angles a fit may read
};

}  // namespace hil::ctl
