// The tracking compensator (docs/tracking_compensator.md has the derivation): the robust
// observer's touch-state test and gap fit, judged by the transducer noise as estimated online
// instead of an assumed figure, and a gap estimator that tracks a growing gap (a level and a
// rate, alpha-beta) instead of holding the last measurement until the next reversal. The law is
// the robust one's: at each motion reversal the command jumps by the distance to the flank ahead
// (a play operator of the commands with the estimated gap), aiming contact_overlap_deg past it.
//
// Noise: the chamber is first order with tau ~ 0.1 s and the drive moves the valve over 5-50 ms,
// so the true pressure's second difference over one period is of the order of 100 Pa, while the
// transducer's white noise of RMS s gives d2 = p(k) - 2 p(k-1) + p(k-2) a variance of 6 s^2 and
// E|d2| = sqrt(2/pi) sqrt(6) s. An exponential mean of |d2| over noise_window_ms, clipped at
// clip_sigmas times the current estimate (a pressure step passes without inflating it), gives s.
#include <algorithm>
#include <cmath>
#include <numbers>

#include "hil/ctl/compensator.hpp"
#include "hil/ctl/observer.hpp"

namespace hil::ctl {
namespace {

// E|d2| / s for white noise: |N(0, 6 s^2)| has the mean sqrt(2/pi) sqrt(6) s.
constexpr double kAbsD2PerSigma = 1.9544100476116797;  // sqrt(12 / pi)

struct TrackingState {
  RobustObserverState obs;
  // transducer noise
  double p1_pa = 0, p2_pa = 0;  // the two previous measurements
  int noise_samples = 0;        // up to 2: d2 needs two previous samples
  double abs_d2_pa = 0;         // exponential mean of |d2|
  // gap: level at the last measurement and its rate; the estimate extrapolates between them
  double gap_level_rad = 0;
  double gap_rate_rad_s = 0;
  double gap_at_s = 0;  // time of the last measurement
  double gap_est_rad = 0;
  int gap_measurements = 0;
  double now_s = 0;
  // the play model of the law, on the motor's angle (the command leads it by the drive's lag)
  double gap_pos_rad = 0;  // believed motor position in the gap
  double motor_prev_rad = 0;
  double cmd_rad = 0;     // the controller's integral command with the jumps, as sent
  double lead_rad = 0;    // the traverse's lead still in cmd_rad (taken back on arrival)
  double target_rad = 0;  // where the traverse takes the motor
  long presume_wait = 0;  // steps before the play model's flank may be trusted
};

class TrackingCompensator final : public CompensatorOf<TrackingCompensator, TrackingState> {
 public:
  static constexpr std::string_view kName = "tracking";
  // In config units; the observer's settings are explained in observer.hpp.
  static constexpr ParamSpec kSpecs[] = {
      {"noise_initial_kpa", 0, 1e4, false, false, 2.0, "transducer noise (RMS) assumed until estimated"},
      {"noise_floor_kpa", 0, 1e4, false, false, 2.0, "the least noise the tests assume (model error of P_eq)"},
      {"noise_window_ms", 1, 1e5, false, false, 200.0, "the noise estimate's averaging time"},
      {"clip_sigmas", 1, 1e3, false, false, 6.0, "a second difference beyond this many sigmas counts as this many"},
      {"intention_deadband_deg", 0, 10, false, false, 0.1, "retreat of the integral command that is a reversal"},
      {"intention_sigmas", 0, 1e3, false, false, 8.0, "reversal threshold on the low-passed error, in its noise sigmas"},
      {"filter_time_constant_ms", 1e-3, 1e4, false, false, 15.0, "each of the two low-pass stages of P_eq"},
      {"hold_smoothing", 1, 100, false, false, 4.0, "the hold level's extra low-pass, in filter time constants"},
      {"time_constant_scale", 1e-3, 2, false, false, 0.9, "factor on the nominal chamber time constant in P_eq"},
      {"detect_sigmas", 1e-3, 1e3, false, false, 5.0, "contact threshold, in sigmas of P_eq's noise"},
      {"confirm_samples", 1, 1000, false, false, 5.0, "samples in a row past the contact threshold", true},
      {"fit_lead_ms", 0, 500, false, false, 20.0, "the gap fit's window starts this long before the motor's extreme"},
      {"fit_after_ms", 1, 500, false, false, 40.0, "the gap fit runs this long after contact"},
      {"fit_tries", 1, 1000, false, false, 8.0, "gap fits while the valve has not moved enough", true},
      {"level_gain", 1e-3, 1, false, false, 1.0, "share of a measurement's innovation taken into the gap level"},
      {"rate_gain", 0, 2, false, false, 1.0, "share of the innovation over the time since the last one taken into the rate"},
      {"rate_max_deg_s", 0, 100, false, false, 1.0, "the largest gap growth (or shrink) rate believed"},
      {"gap_max_deg", 1e-3, 90, false, false, 6.0, "the largest gap a fit may find"},
      {"contact_overlap_deg", 0, 1, false, false, 0.15, "the jump aims this far past the flank"},
      {"lead_lags", 0, 10, false, false, 1.0, "the traverse's command leads the motor by this many slew x drive lag"},
  };

  TrackingCompensator(const CompensatorSetup& setup, std::span<const double> v)
      : setup_(setup),
        observer_(observer_params(setup, v), setup.chamber),
        noise_initial_pa_(v[0] * units::kPaPerKpa),
        noise_floor_pa_(v[1] * units::kPaPerKpa),
        noise_alpha_(1 - std::exp(-setup.period_s / (v[2] * 1e-3))),
        clip_sigmas_(v[3]),
        level_gain_(v[14]),
        rate_gain_(v[15]),
        rate_max_rad_s_(v[16] * units::kRadPerDeg),
        gap_max_rad_(v[17] * units::kRadPerDeg),
        contact_overlap_rad_(v[18] * units::kRadPerDeg),
        lead_rad_(v[19] * setup.motor.rate_limit_rad_s * setup.motor.time_constant_s),
        reach_rad_(setup.motor.rate_limit_rad_s * setup.period_s) {}

  TrackingState initial(double theta_cmd_rad, double p_meas_pa, int touch) const noexcept {
    TrackingState s;
    s.gap_est_rad = setup_.compensation == Compensation::constant ? setup_.gap_known_rad : setup_.gap_initial_rad;
    s.gap_level_rad = s.gap_est_rad;
    s.gap_pos_rad = touch * s.gap_est_rad / 2;
    s.motor_prev_rad = s.cmd_rad = theta_cmd_rad;
    s.p1_pa = s.p2_pa = p_meas_pa;
    s.abs_d2_pa = kAbsD2PerSigma * noise_initial_pa_;
    s.obs = observer_.initial_state(touch, theta_cmd_rad, p_meas_pa, theta_cmd_rad);
    return s;
  }

  void step(TrackingState& s, const CompensatorInputs& in, CompensatorOutputs& out) const noexcept {
    const bool constant = setup_.compensation == Compensation::constant;
    const RobustObserverParams& op = observer_.params();
    s.now_s += setup_.period_s;

    // The transducer noise, from the second difference of the measurements.
    const double noise_pa = std::max(s.abs_d2_pa / kAbsD2PerSigma, noise_floor_pa_);
    if (s.noise_samples >= 2) {
      const double d2 = std::abs(in.p_meas_pa - 2 * s.p1_pa + s.p2_pa);
      const double clip = clip_sigmas_ * kAbsD2PerSigma * std::max(s.abs_d2_pa / kAbsD2PerSigma, noise_floor_pa_);
      s.abs_d2_pa += noise_alpha_ * (std::min(d2, clip) - s.abs_d2_pa);
    } else {
      ++s.noise_samples;
    }
    s.p2_pa = s.p1_pa;
    s.p1_pa = in.p_meas_pa;

    // The play model presumes the motor pushed a flank when it sits within the intention's
    // dead-band of it; with no gap known, or while a jump may still be under way, nothing.
    const double gap_before = constant ? setup_.gap_known_rad : s.gap_est_rad;
    const bool gap_known = constant || s.gap_measurements > 0;
    const double near = gap_before / 2 - op.intention_deadband_rad - 1e-12;
    if (s.presume_wait > 0) --s.presume_wait;
    const int presumed = !gap_known || s.presume_wait > 0 ? 0 : s.gap_pos_rad >= near ? 1 : s.gap_pos_rad <= -near ? -1 : 0;
    ObserverInputs obs_in{in.cmd_step_rad, in.error_pa, in.p_meas_pa, in.motor_rad, in.tau_s, in.volume_m3, presumed};
    obs_in.noise_rms_pa = noise_pa;
    const ObserverOutputs obs = observer_.step(s.obs, obs_in);

    // The gap: level and rate (alpha-beta). A measurement corrects the level extrapolated to now
    // and the rate by the innovation over the time since the last one; between measurements the
    // estimate follows the rate (a gap that wears open keeps opening between reversals).
    if (!constant) {
      if (obs.gap_measured) {
        const double dt_s = s.now_s - s.gap_at_s;
        const double predicted = s.gap_level_rad + s.gap_rate_rad_s * dt_s;
        const double innovation = obs.gap_measured_rad - predicted;
        if (s.gap_measurements++ == 0) {
          s.gap_level_rad = obs.gap_measured_rad;
          s.gap_rate_rad_s = 0;
        } else {
          s.gap_level_rad = predicted + level_gain_ * innovation;
          if (dt_s > 0) {
            s.gap_rate_rad_s = std::clamp(s.gap_rate_rad_s + rate_gain_ * innovation / dt_s, -rate_max_rad_s_, rate_max_rad_s_);
          }
        }
        s.gap_at_s = s.now_s;
      }
      const double before = s.gap_est_rad;
      if (s.gap_measurements > 0) {
        s.gap_est_rad = std::clamp(s.gap_level_rad + s.gap_rate_rad_s * (s.now_s - s.gap_at_s), 0.0, gap_max_rad_);
      }
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
    r.pressure_noise_rms_pa = v[0] * units::kPaPerKpa;  // unused: each step passes the estimate
    r.intention_deadband_rad = v[4] * units::kRadPerDeg;
    r.intention_sigmas = v[5];
    r.filter_time_constant_s = v[6] * 1e-3;
    r.hold_smoothing = v[7];
    r.time_constant_scale = v[8];
    r.detect_sigmas = v[9];
    r.confirm_samples = static_cast<int>(v[10]);
    r.fit_lead_s = v[11] * 1e-3;
    r.fit_after_s = v[12] * 1e-3;
    r.fit_tries = static_cast<int>(v[13]);
    r.learn_gain = 1;  // the gap estimate is this compensator's
    r.jump_fraction = 1;
    r.gap_max_rad = v[17] * units::kRadPerDeg;
    return r;
  }

  CompensatorSetup setup_;
  RobustObserver observer_;
  double noise_initial_pa_, noise_floor_pa_, noise_alpha_, clip_sigmas_;
  double level_gain_, rate_gain_, rate_max_rad_s_, gap_max_rad_;
  double contact_overlap_rad_, lead_rad_, reach_rad_;
};

}  // namespace

HIL_REGISTER_COMPENSATOR(TrackingCompensator,
                         "the robust observer judged by the transducer noise estimated online, a gap estimator with a "
                         "level and a rate that tracks a growing gap, and the jump to the flank ahead")

}  // namespace hil::ctl
