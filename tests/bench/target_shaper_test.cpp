// The targets sent to a real drive: within its velocity and acceleration limits, on the command
// as fast as those limits allow (closed forms of the trapezoidal move), and never past it.
#include <gtest/gtest.h>

#include <cmath>

#include "hil/bench/rt/target_shaper.hpp"

using hil::bench::ShapingLimits;
using hil::bench::TargetShaper;

namespace {

constexpr double kDeg = M_PI / 180;

struct Trace {
  double t_arrive_s = -1, max_v = 0, max_a = 0, overshoot = 0;
};

Trace follow(TargetShaper& s, double from, double to, double dt, double duration_s) {
  Trace tr;
  s.reset(from);
  double v_prev = 0;
  for (int k = 1; k * dt <= duration_s + 1e-12; ++k) {
    const double x = s.step(to, dt);
    const double v = s.velocity_rad_s();
    tr.max_v = std::max(tr.max_v, std::abs(v));
    tr.max_a = std::max(tr.max_a, std::abs(v - v_prev) / dt);
    tr.overshoot = std::max(tr.overshoot, (x - to) * (to > from ? 1 : -1));
    v_prev = v;
    if (tr.t_arrive_s < 0 && std::abs(x - to) < 1e-9 && std::abs(v) < 1e-9) tr.t_arrive_s = k * dt;
  }
  return tr;
}

TEST(TargetShaper, AStepBecomesTheFastestMoveWithinTheLimits) {
  const double vmax = 60 * kDeg, amax = 3000 * kDeg, dt = 1e-3;
  for (const double step_deg : {4.0, -4.0, 0.3, 20.0}) {
    TargetShaper s({vmax, amax});
    const Trace tr = follow(s, 10 * kDeg, (10 + step_deg) * kDeg, dt, 2.0);
    EXPECT_LE(tr.max_v, vmax * (1 + 1e-12)) << step_deg;
    EXPECT_LE(tr.max_a, amax * (1 + 1e-9)) << step_deg;
    EXPECT_LE(tr.overshoot, 1e-12) << step_deg;
    // The continuous-time minimum: a triangle (d < v^2/a) or a trapezoid; the discrete move
    // may take a few periods more, never less.
    const double d = std::abs(step_deg) * kDeg;
    const double t_min = d < vmax * vmax / amax ? 2 * std::sqrt(d / amax) : d / vmax + vmax / amax;
    ASSERT_GT(tr.t_arrive_s, 0) << step_deg;
    EXPECT_GE(tr.t_arrive_s, t_min - dt) << step_deg;
    EXPECT_LE(tr.t_arrive_s, t_min + 5 * dt) << step_deg;
  }
}

TEST(TargetShaper, WithoutLimitsTheTargetIsTheCommand) {
  TargetShaper s;
  s.reset(0.1);
  EXPECT_EQ(s.step(0.5, 1e-3), 0.5);
  EXPECT_EQ(s.step(-0.2, 1e-3), -0.2);
}

TEST(TargetShaper, FollowsAMovingCommandAndReversesWithinTheLimits) {
  const double vmax = 60 * kDeg, amax = 3000 * kDeg, dt = 1e-3;
  TargetShaper s({vmax, amax});
  s.reset(0);
  double v_prev = 0, worst_lag = 0;
  for (int k = 1; k <= 4000; ++k) {
    const double t = k * dt;
    const double cmd = 5 * kDeg * std::sin(2 * M_PI * 0.5 * t) + (t > 2 ? 3 * kDeg : 0);  // slow sine, then a jump
    const double x = s.step(cmd, dt);
    EXPECT_LE(std::abs(s.velocity_rad_s()), vmax * (1 + 1e-12));
    EXPECT_LE(std::abs(s.velocity_rad_s() - v_prev) / dt, amax * (1 + 1e-9));
    v_prev = s.velocity_rad_s();
    if (t < 1.9 && t > 0.1) worst_lag = std::max(worst_lag, std::abs(x - cmd));
  }
  // A 0.5 Hz, 5 deg sine asks at most 15.7 deg/s and 49 deg/s^2: followed within a few periods' motion.
  EXPECT_LT(worst_lag, 0.05 * kDeg);
}

}  // namespace
