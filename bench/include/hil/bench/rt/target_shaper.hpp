// The position targets a real drive is sent: the controller's command followed within the drive's
// velocity and acceleration limits. In cyclic synchronous position mode a drive interpolates
// between SYNC targets, so a 4 deg compensation jump in one period is a 4 deg following error
// (and, with a normal following-error window, a drive fault). The shaper turns such a step into
// the fastest trajectory the drive can follow: accelerate at the limit, cruise at the velocity
// limit, brake at the limit to stop on the command. The controller's own view is unchanged: it
// keeps its command; only the rig is sent the shaped target. Pure and real-time safe.
#pragma once

#include <algorithm>
#include <cmath>

namespace hil::bench {

struct ShapingLimits {
  double max_velocity_rad_s = 0;  // <= 0: no shaping (the target is the command)
  double max_acceleration_rad_s2 = 0;
  bool enabled() const noexcept { return max_velocity_rad_s > 0 && max_acceleration_rad_s2 > 0; }
};

class TargetShaper {
 public:
  TargetShaper() = default;
  explicit TargetShaper(ShapingLimits limits) noexcept : l_(limits) {}

  // Starts at rest at `position_rad` (the drive's own target at the start of a run).
  void reset(double position_rad) noexcept {
    x_rad_ = x_sent_rad_ = position_rad;
    v_rad_s_ = v_sent_rad_s_ = 0;
  }

  // The next period's target toward `command_rad`. Real-time safe.
  //
  // `previous_sent`: the last target went out to the drive (a CAN drive: a SYNC carried it). When
  // it did not (the loop wrote twice before the drive's I/O thread sent one SYNC, on a loaded
  // host), the drive never sees it: the step is taken again from the last target sent, so that
  // consecutive targets on the bus differ by one step within the limits. Stepping on from the
  // unsent one made the drive see two steps between two SYNCs (180 deg/s under a 60 deg/s limit).
  double step(double command_rad, double dt_s, bool previous_sent = true) noexcept {
    if (previous_sent) {
      x_sent_rad_ = x_rad_;
      v_sent_rad_s_ = v_rad_s_;
    } else {
      x_rad_ = x_sent_rad_;
      v_rad_s_ = v_sent_rad_s_;
    }
    if (!l_.enabled() || !(dt_s > 0) || !std::isfinite(command_rad)) {
      x_rad_ = command_rad;
      v_rad_s_ = 0;
      return x_rad_;
    }
    const double e = command_rad - x_rad_;
    const double a_dt = l_.max_acceleration_rad_s2 * dt_s;
    // The fastest speed from which this period's move plus braking at the limit (a_dt less each
    // period) still stops on the command: with v = (m + r) a_dt the whole way is
    // a dt^2 (m + 1)(m/2 + r), solved for the whole m and the fraction r. Exact in discrete
    // time, so the target never passes the command.
    const double steps = std::abs(e) / (a_dt * dt_s);
    const double m = std::floor((std::sqrt(1 + 8 * steps) - 1) / 2);
    const double r = std::clamp(steps / (m + 1) - m / 2, 0.0, 1.0);
    const double v_want = std::copysign(std::min(l_.max_velocity_rad_s, a_dt * (m + r)), e);
    v_rad_s_ += std::clamp(v_want - v_rad_s_, -a_dt, a_dt);
    x_rad_ += v_rad_s_ * dt_s;
    return x_rad_;
  }

  double position_rad() const noexcept { return x_rad_; }
  double velocity_rad_s() const noexcept { return v_rad_s_; }
  const ShapingLimits& limits() const noexcept { return l_; }

 private:
  ShapingLimits l_;
  double x_rad_ = 0, v_rad_s_ = 0;
  double x_sent_rad_ = 0, v_sent_rad_s_ = 0;  // the last target known to have gone out, and its speed
};

}  // namespace hil::bench
