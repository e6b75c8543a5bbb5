// The tracking compensator (docs/tracking_compensator.md has the derivation): the robust
// observer's touch-state test and gap fit, judged by the transducer noise as estimated online
// instead of an assumed figure, and a gap estimator that tracks a growing gap (a level and a
// rate, alpha-beta) instead of holding the last measurement until the next reversal. The law is
// the robust one's (at each motion reversal a jump to the flank ahead, contact_overlap_deg past
// it) made aware of the drive's lag: the play model of the gap runs on the motor's angle, not on
// the command that leads it, and the jump carries a lead of slew x lag, taken back on arrival.
// While the motor is inside the gap the command's steps are low-passed (the valve stands there,
// so their noise is only stall).
//
// The noise estimator, the gap tracker and the in-gap step filter are in hil/ctl/tracking.hpp.
#include <algorithm>
#include <array>
#include <cmath>

#include "hil/ctl/compensator.hpp"
#include "hil/ctl/observer.hpp"
#include "hil/ctl/observer_specs.hpp"
#include "hil/ctl/tracking.hpp"

namespace hil::ctl {
namespace {

struct TrackingState {
  RobustObserverState obs;
  NoiseEstimator::State noise;
  GapTracker::State gap;  // level and rate; the estimate extrapolates between measurements
  double gap_est_rad = 0;
  double now_s = 0;
  // the play model of the law, on the motor's angle (the command leads it by the drive's lag)
  double gap_pos_rad = 0;  // believed motor position in the gap
  double motor_prev_rad = 0;
  double cmd_rad = 0;           // the controller's integral command with the jumps, as sent
  double lead_rad = 0;          // the traverse's lead still in cmd_rad (taken back on arrival)
  double target_rad = 0;        // where the traverse takes the motor
  long presume_wait = 0;        // steps before the play model's flank may be trusted
  double ki_dt_rad_per_pa = 0;  // the integral controller's KI x period, as it last showed
  double contact_s = 0;         // when the observer last confirmed contact with a flank
  double held_rad = 0;          // the command's steps held back while the motor is in the gap
};

class TrackingCompensator final : public CompensatorOf<TrackingCompensator, TrackingState> {
 public:
  static constexpr std::string_view kName = "tracking";
  // In config units: the noise estimator, the observer's shared rows (observer_specs.hpp), the
  // gap tracker and the law.
  static constexpr auto kSpecs = join_specs(
      std::array<ParamSpec, 5>{{
          {"noise_initial_kpa", 0, 1e4, false, false, 2.0, "transducer noise (RMS) assumed until estimated"},
          {"noise_floor_kpa", 0, 1e4, false, false, 2.0, "the least noise the tests assume (model error of P_eq)"},
          {"noise_window_ms", 1, 1e5, false, false, 200.0, "the noise estimate's averaging time"},
          {"clip_sigmas", 1, 1e3, false, false, 6.0, "a second difference beyond this many sigmas counts as this many"},
          with_fallback(kIntentionDeadbandSpec, 0.1),
      }},
      kObserverSpecs,
      std::array<ParamSpec, 10>{{
          {"level_gain", 1e-3, 1, false, false, 1.0, "share of a measurement's innovation taken into the gap level"},
          {"rate_gain", 0, 2, false, false, 1.0, "share of the innovation over the time since the last one taken into the rate"},
          {"rate_max_deg_s", 0, 100, false, false, 1.0, "the largest gap growth (or shrink) rate believed"},
          kGapMaxSpec,
          with_fallback(kContactOverlapSpec, 0.15),
          {"lead_lags", 0, 10, false, false, 1.0, "the traverse's command leads the motor by this many slew x drive lag"},
          {"gap_prior_deg", 0, 90, false, false, 2.0, "the least gap the law assumes until one is measured (adaptive)"},
          {"damping_gain", 0, 2, false, false, 1.0,
           "share of tau x dP/dt added to the integral's error (1: it integrates P_eq - P_ref)"},
          {"damping_sigmas", 0, 100, false, false, 1.0, "tau x dP/dt within this many sigmas of P_eq's noise is not added"},
          {"gap_filter_ms", 0, 1e3, false, false, 30.0,
           "inside the gap the command's steps are low-passed with this time constant (0: not)"},
      }});
  // Where each value sits in kSpecs.
  enum : std::size_t {
    kNoiseInitial,
    kNoiseFloor,
    kNoiseWindow,
    kClip,
    kDeadband,
    kObserver,
    kLevelGain = kObserver + kObserverSpecs.size(),
    kRateGain,
    kRateMax,
    kGapMax,
    kOverlap,
    kLeadLags,
    kGapPrior,
    kDampingGain,
    kDampingSigmas,
    kGapFilter
  };

  TrackingCompensator(const CompensatorSetup& setup, std::span<const double> v)
      : setup_(setup),
        observer_(observer_params(setup, v), setup.chamber),
        noise_initial_pa_(v[kNoiseInitial] * units::kPaPerKpa),
        noise_{1 - std::exp(-setup.period_s / (v[kNoiseWindow] * 1e-3)), v[kNoiseFloor] * units::kPaPerKpa, v[kClip]},
        tracker_{v[kLevelGain], v[kRateGain], v[kRateMax] * units::kRadPerDeg, v[kGapMax] * units::kRadPerDeg},
        contact_overlap_rad_(v[kOverlap] * units::kRadPerDeg),
        lead_rad_(v[kLeadLags] * setup.motor.rate_limit_rad_s * setup.motor.time_constant_s),
        reach_rad_(setup.motor.rate_limit_rad_s * setup.period_s),
        gap_prior_rad_(v[kGapPrior] * units::kRadPerDeg),
        damping_gain_(v[kDampingGain]),
        damping_sigmas_(v[kDampingSigmas]),
        gap_filter_{v[kGapFilter] > 0 ? 1 - std::exp(-setup.period_s / (v[kGapFilter] * 1e-3)) : 1.0} {}

  TrackingState initial(double theta_cmd_rad, double p_meas_pa, int touch) const noexcept {
    TrackingState s;
    s.gap_est_rad =
        setup_.compensation == Compensation::constant ? setup_.gap_known_rad : std::max(setup_.gap_initial_rad, gap_prior_rad_);
    s.gap_pos_rad = touch * s.gap_est_rad / 2;
    s.motor_prev_rad = s.cmd_rad = theta_cmd_rad;
    s.noise = noise_.initial(p_meas_pa, noise_initial_pa_);
    s.obs = observer_.initial_state(touch, theta_cmd_rad, p_meas_pa, theta_cmd_rad);
    return s;
  }

  void step(TrackingState& s, const CompensatorInputs& in, CompensatorOutputs& out) const noexcept {
    const bool constant = setup_.compensation == Compensation::constant;
    const RobustObserverParams& op = observer_.params();
    s.now_s += setup_.period_s;

    // The transducer noise, from the second difference of the measurements.
    const double noise_pa = noise_.update(s.noise, in.p_meas_pa);

    // The play model presumes the motor pushed a flank when it sits within the intention's
    // dead-band of it; with no gap known, or while a jump may still be under way, nothing.
    const double gap_before = constant ? setup_.gap_known_rad : s.gap_est_rad;
    const bool gap_known = constant || s.gap.measurements > 0;
    const double near = gap_before / 2 - op.intention_deadband_rad - 1e-12;
    if (s.presume_wait > 0) --s.presume_wait;
    const int presumed = !gap_known || s.presume_wait > 0 ? 0 : s.gap_pos_rad >= near ? 1 : s.gap_pos_rad <= -near ? -1 : 0;
    ObserverInputs obs_in{in.cmd_step_rad, in.error_pa, in.p_meas_pa, in.motor_rad, in.tau_s, in.volume_m3, presumed};
    obs_in.noise_rms_pa = noise_pa;
    const int touch_before = s.obs.touch;
    const ObserverOutputs obs = observer_.step(s.obs, obs_in);
    if (obs.touch != 0 && touch_before == 0) s.contact_s = s.now_s;

    // The gap: level and rate (alpha-beta). A measurement corrects the level extrapolated to its
    // time and the rate by the innovation over the time since the last one; between measurements
    // the estimate follows the rate (a gap that wears open keeps opening between reversals).
    if (!constant) {
      // The fit measures the motor's travel from its last push on the old flank (the observer's
      // sample; its history counts these periods: sample i ends at (i + 1) periods) to the
      // contact with the new one (when the observer confirmed it, a few filter constants late).
      // The old push may be most of a reversal interval old: the damped loop (below) settles a
      // step without a second push and the motor then holds still until the next reversal, so
      // the measurement taken as of now would put a gap growing at 0.5 deg/s up to 0.3 deg behind.
      if (obs.gap_measured)
        tracker_.measure_travel(s.gap, obs.gap_measured_rad,
                                static_cast<double>(s.obs.transition_extreme_at + 1) * setup_.period_s, s.contact_s);
      const double before = s.gap_est_rad;
      s.gap_est_rad = tracker_.estimate_rad(s.gap, s.now_s, s.gap_est_rad);
      // Where the motor sits in the gap, in the new gap: on a flank it stays on that flank.
      if (before > 0 && s.gap_est_rad != before) s.gap_pos_rad *= s.gap_est_rad / before;
    }
    const double gap = constant ? setup_.gap_known_rad : s.gap_est_rad;
    // The play model follows the motor, not the command: with a drive lag tau_m the command
    // leads the motor by about tau_m times its speed, and a jump sized from the command would
    // stop that much short of the flank ahead.
    s.gap_pos_rad += in.motor_rad - s.motor_prev_rad;
    s.motor_prev_rad = in.motor_rad;
    s.cmd_rad += in.cmd_step_rad;
    out.reversed = obs.reversed;
    // Damping (docs/tracking_compensator.md section 5): the integral controller integrates
    // P - P_ref, which lags the valve by the chamber's tau, so it winds on after the valve has
    // gone far enough and the loop rings: an undershoot after a step, then an overshoot, each a
    // reversal and a crossing of the whole gap. Adding KI dT tau LP(dP/dt) to the command makes
    // it integrate P_eq - P_ref = LP(P) + tau LP(dP/dt) - P_ref, the pressure the valve holds now:
    // the chamber's lag is cancelled and the loop no longer overshoots. KI dT is the controller's
    // own, read from its step (cmd_step = KI dT error); tau dP/dt within damping_sigmas of P_eq's
    // noise is left out, so the transducer's noise does not walk the motor across the gap.
    double step_rad = in.cmd_step_rad;  // the command's step this period, the integral's and the damping's
    if (in.error_pa != 0) s.ki_dt_rad_per_pa = in.cmd_step_rad / in.error_pa;
    if (setup_.compensation != Compensation::none && damping_gain_ > 0) {
      const double lead_pa = s.obs.p_eq_pa - s.obs.p_lp2;  // tau LP(dP/dt)
      const double quiet_pa = damping_sigmas_ * observer_.p_eq_noise_pa(in.tau_s, noise_pa);
      const double damp_rad =
          damping_gain_ * s.ki_dt_rad_per_pa * std::copysign(std::max(std::abs(lead_pa) - quiet_pa, 0.0), lead_pa);
      out.comp_rad += damp_rad;
      s.cmd_rad += damp_rad;
      step_rad += damp_rad;
    }
    // Inside the gap (docs/tracking_compensator.md section 6) the valve stands, so the command's
    // noise only shakes the motor there: at 10 kPa and a 5 ms drive lag that shaking was most of
    // the stall at gaps of 0.2-0.35 deg. The steps are low-passed while the play model puts the
    // motor clear of both flanks (a known gap, no traverse under way); at a flank all passes.
    if (setup_.compensation != Compensation::none) {
      const bool in_gap =
          gap_known && s.presume_wait == 0 && s.lead_rad == 0 && std::abs(s.gap_pos_rad) < gap / 2 - kFlankMarginRad;
      const double held_back_rad = gap_filter_.pass_rad(s.held_rad, step_rad, in_gap) - step_rad;
      out.comp_rad += held_back_rad;
      s.cmd_rad += held_back_rad;
    }
    // The traverse's lead comes back out of the command once the motor will reach the target
    // within this step (at the slew limit), as the controller's own boost does.
    if (s.lead_rad != 0 && s.lead_rad * (s.target_rad - in.motor_rad) <= reach_rad_ * std::abs(s.lead_rad)) {
      out.comp_rad -= s.lead_rad;
      s.cmd_rad -= s.lead_rad;
      s.lead_rad = 0;
    }
    if (setup_.compensation != Compensation::none && obs.reversed) {
      const int d = obs.intention;
      // A lead still pending belongs to the traverse this reversal cancels.
      out.comp_rad -= s.lead_rad;
      s.cmd_rad -= s.lead_rad;
      s.lead_rad = 0;
      s.gap_pos_rad = std::clamp(s.gap_pos_rad, -gap / 2, gap / 2);
      // The motor's target: past the flank ahead; the jump takes the command there.
      s.target_rad = in.motor_rad + d * (std::max(gap / 2 - d * s.gap_pos_rad, 0.0) + contact_overlap_rad_);
      if (d * (s.target_rad - s.cmd_rad) > 0) {
        // Drive lag: a first-order servo moves at (command - angle) / tau_m, so it reaches its
        // slew limit only with the command slew x tau_m ahead; a small jump alone would creep
        // across the gap. The lead (lead_lags of that) is added now and taken back on arrival.
        const double travel_rad = std::abs(s.target_rad - in.motor_rad);
        s.lead_rad = d * std::max(lead_rad_ - travel_rad, 0.0);
        const double jump_rad = s.target_rad - s.cmd_rad + s.lead_rad;
        out.comp_rad += jump_rad;
        s.cmd_rad += jump_rad;
        s.held_rad = 0;  // the jump aims the command itself: steps held back before it are void
        // The drive needs the crossing at its slew limit plus a few lags to really get there.
        s.presume_wait =
            std::lround((travel_rad / setup_.motor.rate_limit_rad_s + 3 * setup_.motor.time_constant_s) / setup_.period_s);
      }
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
    r.pressure_noise_rms_pa = v[kNoiseInitial] * units::kPaPerKpa;  // unused: each step passes the estimate
    r.intention_deadband_rad = v[kDeadband] * units::kRadPerDeg;
    apply_observer_specs(r, v.subspan(kObserver, kObserverSpecs.size()));
    r.learn_gain = 1;  // the gap estimate is this compensator's
    r.jump_fraction = 1;
    r.gap_max_rad = v[kGapMax] * units::kRadPerDeg;
    return r;
  }

  CompensatorSetup setup_;
  RobustObserver observer_;
  double noise_initial_pa_;
  NoiseEstimator noise_;
  GapTracker tracker_;
  double contact_overlap_rad_, lead_rad_, reach_rad_, gap_prior_rad_;
  double damping_gain_, damping_sigmas_;
  GapStepFilter gap_filter_;
  // The motor counts as in the gap only this far clear of a flank (0.01 deg): at the flank it
  // pushes, the command's noise moves it back by thousandths of a degree, which must not turn the
  // filter on while the valve is coupled.
  static constexpr double kFlankMarginRad = 0.01 * units::kRadPerDeg;
};

}  // namespace

HIL_REGISTER_COMPENSATOR(TrackingCompensator,
                         "the robust observer judged by the transducer noise estimated online, a gap estimator with a "
                         "level and a rate that tracks a growing gap, and the jump to the flank ahead")

}  // namespace hil::ctl
