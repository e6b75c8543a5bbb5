// The robust compensator: this project's touch-state observer (RobustObserver, observer.hpp) and
// its law. The controller keeps where the motor sits in the gap, a play operator of the commands
// with the estimated gap (gap_pos in [-sigma/2, +sigma/2], +sigma/2 = resting on the flank that
// opens the valve). At each motion reversal the command jumps by exactly the distance to the
// flank ahead; reversals inside the gap jump only what is left. The jump aims contact_overlap_deg
// past the flank, so contact is made while the motor still moves (the motion the reversal asked
// for absorbs that much). The gap estimate takes each measurement of the observer part way
// (learn_gain), or whole when it is the first or shows a real change (jump_fraction).
#include <algorithm>
#include <array>
#include <cmath>

#include "hil/ctl/compensator.hpp"
#include "hil/ctl/observer.hpp"
#include "hil/ctl/observer_specs.hpp"

namespace hil::ctl {
namespace {

struct RobustState {
  RobustObserverState obs;
  double gap_est_rad = 0;
  double gap_pos_rad = 0;  // believed motor position in the gap
  long presume_wait = 0;   // steps before the play model's flank may be trusted
  int gap_measurements = 0;
};

class RobustCompensator final : public CompensatorOf<RobustCompensator, RobustState> {
 public:
  static constexpr std::string_view kName = "robust";
  // In config units: the noise it assumes, the observer's shared rows (observer_specs.hpp), the
  // gap estimate's update and the law's overlap.
  static constexpr auto kSpecs = join_specs(
      std::array<ParamSpec, 2>{
          {{"pressure_noise_kpa", 0, 1e4, false, false, 2.0, "the transducer noise the observer assumes (RMS)"},
           kIntentionDeadbandSpec}},
      kObserverSpecs,
      std::array<ParamSpec, 4>{
          {{"learn_gain", 1e-3, 1, false, false, 0.8, "share of a gap measurement taken into the estimate"},
           {"jump_fraction", 1e-3, 10, false, false, 0.2, "a measurement this far from the estimate (fraction) is taken whole"},
           kGapMaxSpec,
           kContactOverlapSpec}});
  // Where each value sits in kSpecs.
  enum : std::size_t {
    kNoise,
    kDeadband,
    kObserver,
    kLearnGain = kObserver + kObserverSpecs.size(),
    kJumpFraction,
    kGapMax,
    kOverlap
  };

  RobustCompensator(const CompensatorSetup& setup, std::span<const double> v)
      : setup_(setup),
        observer_(observer_params(setup, v), setup.chamber),
        contact_overlap_rad_(v[kOverlap] * units::kRadPerDeg) {}

  RobustState initial(double theta_cmd_rad, double p_meas_pa, int touch) const noexcept {
    RobustState s;
    s.gap_est_rad = setup_.compensation == Compensation::constant ? setup_.gap_known_rad : setup_.gap_initial_rad;
    s.gap_pos_rad = touch * s.gap_est_rad / 2;
    s.obs = observer_.initial_state(touch, theta_cmd_rad, p_meas_pa, theta_cmd_rad);
    return s;
  }

  void step(RobustState& s, const CompensatorInputs& in, CompensatorOutputs& out) const noexcept {
    const bool constant = setup_.compensation == Compensation::constant;
    const RobustObserverParams& op = observer_.params();
    // The play model presumes the motor pushed a flank when it sits within the intention's
    // dead-band of it (a reversal is only seen after that retreat); with no gap known, or while a
    // jump may still be under way in the drive, nothing.
    const double gap_before = constant ? setup_.gap_known_rad : s.gap_est_rad;
    const bool gap_known = constant || s.gap_measurements > 0;
    const double near = gap_before / 2 - op.intention_deadband_rad - 1e-12;
    if (s.presume_wait > 0) --s.presume_wait;
    const int presumed = !gap_known || s.presume_wait > 0 ? 0 : s.gap_pos_rad >= near ? 1 : s.gap_pos_rad <= -near ? -1 : 0;
    const ObserverInputs obs_in{in.cmd_step_rad, in.error_pa, in.p_meas_pa, in.motor_rad, in.tau_s, in.volume_m3, presumed};
    const ObserverOutputs obs = observer_.step(s.obs, obs_in);

    // Measured gaps; with compensation `none` still learned (observe only) so telemetry shows what
    // it would do. The first measurement, and one showing a real change, replace the estimate;
    // the others move it part way (averaging the measurement noise).
    if (!constant && obs.gap_measured) {
      const double innovation = obs.gap_measured_rad - s.gap_est_rad;
      const bool jump = std::abs(innovation) > op.jump_fraction * s.gap_est_rad;
      const double gain = s.gap_measurements++ == 0 || jump ? 1.0 : op.learn_gain;
      const double before = s.gap_est_rad;
      s.gap_est_rad += gain * innovation;
      // Where the motor sits in the gap, in the new gap: on a flank it stays on that flank.
      if (before > 0) s.gap_pos_rad *= s.gap_est_rad / before;
    }
    const double gap = constant ? setup_.gap_known_rad : s.gap_est_rad;  // as updated
    s.gap_pos_rad += in.cmd_step_rad;
    out.reversed = obs.reversed;
    if (setup_.compensation != Compensation::none && obs.reversed) {
      const int d = obs.intention;
      out.comp_rad = d * (std::max(gap / 2 - d * s.gap_pos_rad, 0.0) + contact_overlap_rad_);  // past the flank ahead
      s.gap_pos_rad += out.comp_rad;
      // The drive needs the crossing at its slew limit plus a few lags to really get there.
      s.presume_wait = std::lround((std::abs(out.comp_rad) / setup_.motor.rate_limit_rad_s + 3 * setup_.motor.time_constant_s) /
                                   setup_.period_s);
    }
    s.gap_pos_rad = std::clamp(s.gap_pos_rad, -gap / 2, gap / 2);  // at a flank: pushing the valve

    out.touch = obs.touch;
    out.intention = obs.intention;
    out.gap_est_rad = s.gap_est_rad;
    out.gap_measured = obs.gap_measured;
  }

 private:
  static RobustObserverParams observer_params(const CompensatorSetup& setup, std::span<const double> v) {
    RobustObserverParams r;
    r.period_s = setup.period_s;
    r.pressure_noise_rms_pa = v[kNoise] * units::kPaPerKpa;
    r.intention_deadband_rad = v[kDeadband] * units::kRadPerDeg;
    apply_observer_specs(r, v.subspan(kObserver, kObserverSpecs.size()));
    r.learn_gain = v[kLearnGain];
    r.jump_fraction = v[kJumpFraction];
    r.gap_max_rad = v[kGapMax] * units::kRadPerDeg;
    return r;
  }

  CompensatorSetup setup_;
  RobustObserver observer_;
  double contact_overlap_rad_;
};

}  // namespace

HIL_REGISTER_COMPENSATOR(RobustCompensator,
                         "this project's observer (equilibrium pressure, noise-aware contact test, measured gap) and "
                         "the jump to the flank ahead")

}  // namespace hil::ctl
