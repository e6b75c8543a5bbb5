// The two estimators and the in-gap step filter of the tracking compensator
// (controller/src/compensators/tracking.cpp, derivation in docs/tracking_compensator.md), apart
// so they can be tested against closed forms.
// Real-time safe: plain state, noexcept, no allocation.
#pragma once

#include <algorithm>
#include <cmath>

namespace hil::ctl {

// The transducer's white noise (RMS) from the second difference of the measurements:
// d2 = p(k) - 2 p(k-1) + p(k-2) has the variance 6 s^2 from noise of RMS s, and for Gaussian
// noise E|d2| = sqrt(2/pi) sqrt(6) s = sqrt(12/pi) s. The chamber (tau ~ 0.1 s) and the drive
// (5-50 ms) make the true pressure's d2 over 1 ms of the order of 100 Pa, so |d2| is noise. An
// exponential mean of |d2|, each sample clipped at clip_sigmas of the current estimate (a
// pressure step or a spike passes without inflating it), divided by sqrt(12/pi), is s.
struct NoiseEstimator {
  static constexpr double kAbsD2PerSigma = 1.9544100476116797;  // sqrt(12 / pi)
  struct State {
    double p1_pa = 0, p2_pa = 0;  // the two previous measurements
    int samples = 0;              // up to 2: d2 needs two previous samples
    double abs_d2_pa = 0;         // exponential mean of |d2|
  };
  double alpha = 0.005;  // per-sample factor of the exponential mean (period / window)
  double floor_pa = 0;   // the least noise reported
  double clip_sigmas = 6;

  State initial(double p_meas_pa, double noise_initial_pa) const noexcept {
    return {p_meas_pa, p_meas_pa, 0, kAbsD2PerSigma * noise_initial_pa};
  }
  double estimate_pa(const State& s) const noexcept { return std::max(s.abs_d2_pa / kAbsD2PerSigma, floor_pa); }
  // Takes one measurement; returns the estimate from the samples before it.
  double update(State& s, double p_meas_pa) const noexcept {
    const double noise_pa = estimate_pa(s);
    if (s.samples >= 2) {
      const double d2 = std::abs(p_meas_pa - 2 * s.p1_pa + s.p2_pa);
      s.abs_d2_pa += alpha * (std::min(d2, clip_sigmas * kAbsD2PerSigma * noise_pa) - s.abs_d2_pa);
    } else {
      ++s.samples;
    }
    s.p2_pa = s.p1_pa;
    s.p1_pa = p_meas_pa;
    return noise_pa;
  }
};

// A gap that drifts, from measurements at irregular times (one per motion reversal at best): a
// level and a rate (an alpha-beta tracker). A measurement z at time t corrects the prediction
// g = level + rate (t - t_last) by the innovation e = z - g: level = g + level_gain e,
// rate += rate_gain e / (t - t_last), clamped to +-rate_max. Between measurements the estimate
// is the prediction, clamped to [0, gap_max]. With both gains 1 a gap growing at a constant
// rate is predicted exactly from the second measurement on; a gap that stops growing costs one
// measurement interval of overshoot before the rate learns it.
struct GapTracker {
  struct State {
    double level_rad = 0;
    double rate_rad_s = 0;
    double at_s = 0;  // time of the last measurement
    int measurements = 0;
  };
  double level_gain = 1;
  double rate_gain = 1;
  double rate_max_rad_s = 0.02;
  double gap_max_rad = 0.1;

  void measure(State& s, double gap_rad, double now_s) const noexcept {
    const double dt_s = now_s - s.at_s;
    const double predicted = s.level_rad + s.rate_rad_s * dt_s;
    const double innovation = gap_rad - predicted;
    if (s.measurements++ == 0) {
      s.level_rad = gap_rad;
      s.rate_rad_s = 0;
    } else {
      s.level_rad = predicted + level_gain * innovation;
      if (dt_s > 0) s.rate_rad_s = std::clamp(s.rate_rad_s + rate_gain * innovation / dt_s, -rate_max_rad_s, rate_max_rad_s);
    }
    s.at_s = now_s;
  }
  // A gap measured as the motor's travel from its last push on one flank (at old_push_s) to its
  // contact with the other (at contact_s): the play is symmetric about the motor, so the travel
  // is half the gap at the one plus half the gap at the other, the gap at their midpoint for a
  // growth linear over that time. Taken as of then (not before the last measurement).
  void measure_travel(State& s, double gap_rad, double old_push_s, double contact_s) const noexcept {
    measure(s, gap_rad, std::max(0.5 * (old_push_s + contact_s), s.at_s));
  }
  // The gap now; `fallback` before the first measurement.
  double estimate_rad(const State& s, double now_s, double fallback) const noexcept {
    if (s.measurements == 0) return fallback;
    return std::clamp(s.level_rad + s.rate_rad_s * (now_s - s.at_s), 0.0, gap_max_rad);
  }
};

// The command's steps while the motor is inside the gap (docs/tracking_compensator.md section 6).
// There the valve stands whatever the motor does, so the command's high-frequency part (the
// integral's share of the transducer noise, KI dT per Pa every period) moves nothing the loop can
// see and is stall when the motor's speed exceeds the metric's threshold. In the gap the steps
// are low-passed (a first-order lag of time constant T: alpha = 1 - exp(-dT / T) of what is held
// back passes each period); at a flank, or while a traverse is under way, all that is held passes
// at once. No step is lost: what passed plus what is held is the sum of the steps.
struct GapStepFilter {
  double alpha = 1;  // per-period share of the held steps that passes in the gap (1: no filter)

  // Takes one period's command step; returns what of the steps reaches the command this period.
  double pass_rad(double& held_rad, double step_rad, bool in_gap) const noexcept {
    held_rad += step_rad;
    const double passed_rad = in_gap ? alpha * held_rad : held_rad;
    held_rad -= passed_rad;
    return passed_rad;
  }
};

}  // namespace hil::ctl
