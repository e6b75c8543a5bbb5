// The controller's step: real-time safe, and the jumps it makes.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include "alloc_counter.hpp"
#include "nominal_model.hpp"

using namespace hil::ctl;
using hil::test::nominal_params;

namespace {

constexpr double kDeg = M_PI / 180;

static_assert(noexcept(std::declval<const Controller&>().step(std::declval<ControllerState&>(), ControllerInputs{})));

// Every registered compensator (this program links the library whole, so every one shipped),
// under every law, through reversals: the square wave of the error makes the intention flip.
TEST(Controller, StepAllocatesNothingWithEveryCompensator) {
  const auto names = compensator_names();
  ASSERT_GE(names.size(), 2u);
  for (const auto& name : names) {
    for (auto law : {Compensation::none, Compensation::constant, Compensation::adaptive}) {
      SCOPED_TRACE(name + " " + compensation_name(law));
      const Controller c(nominal_params(law, name.c_str()));
      auto s = c.initial_state(11 * kDeg, 1e6, +1);
      int reversals = 0, last = 0;
      const long before = hil::test::allocations();
      for (int k = 0; k < 20000; ++k) {
        const double p = 1e6 + ((k / 500) % 2 == 0 ? 5e4 : -5e4) + 3e4 * std::sin(k * 1e-3 * 3) + (k % 7) * 300.0;
        const auto out = c.step(s, {p, 1e6, s.motor_model_rad});
        if (out.motion_intention != 0 && out.motion_intention != last) ++reversals;
        if (out.motion_intention != 0) last = out.motion_intention;
      }
      EXPECT_EQ(hil::test::allocations() - before, 0);
      EXPECT_GE(reversals, 10);  // the period's branches of a reversal ran
    }
  }
}

TEST(Controller, UnknownCompensatorOrParameterIsRejectedNamingIt) {
  auto p = nominal_params(Compensation::adaptive, "nonesuch");
  try {
    Controller{p};
    FAIL() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("no compensator 'nonesuch'; registered: paper, robust, tracking"), std::string::npos)
        << e.what();
  }
  p = nominal_params(Compensation::adaptive, "robust");
  p.compensator_params = param_defaults(find_compensator("robust")->specs);
  p.compensator_params[7] = 2.5;  // confirm_samples
  try {
    Controller{p};
    FAIL() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("compensator robust.confirm_samples = 2.5: must be a whole number in [1, 1000]"),
              std::string::npos)
        << e.what();
  }
}

TEST(Controller, IntegralLawHasTheStabilisingSign) {
  const Controller c(nominal_params(Compensation::none, "robust"));
  auto s = c.initial_state(11 * kDeg, 1e6, +1);
  const double ki = c.ki_rad_per_pa_s(1e6, 2e-3);
  const auto out = c.step(s, {1.01e6, 1e6, 11 * kDeg});
  // Pressure 10 kPa too high -> open the valve by KI dT dPg.
  EXPECT_NEAR(out.theta_cmd_rad - 11 * kDeg, ki * 1e-3 * 1e4, 1e-12);
}

TEST(Controller, PaperConstantJumpsExactlySigma) {
  const Controller c(nominal_params(Compensation::constant, "paper"));
  auto s = c.initial_state(11 * kDeg, 1e6, +1);
  const auto out = c.step(s, {0.99e6, 1e6, 11 * kDeg});  // too low: close, leaving the + flank
  EXPECT_NEAR(out.comp_rad, -1 * kDeg, 1e-15);
  EXPECT_EQ(out.touch_state, 0);
}

TEST(Controller, RobustJumpCrossesToTheFlankAheadAndBoostsTheCrossing) {
  auto p = nominal_params(Compensation::constant, "robust");
  const Controller c(p);
  auto s = c.initial_state(11 * kDeg, 1e6, +1);  // resting on the opening flank
  ControllerOutputs out;
  int k = 0;
  for (; k < 100; ++k) {
    out = c.step(s, {0.95e6, 1e6, s.motor_model_rad});  // 50 kPa low: close
    if (out.comp_rad != 0) break;
  }
  ASSERT_LT(k, 100);
  // The jump covers what the gap has left ahead (sigma minus what the integral already walked)
  // plus the contact overlap.
  const double walked = 11 * kDeg - (s.theta_cmd_rad - out.comp_rad);
  const double overlap = 0.02 * kDeg;  // the robust compensator's contact_overlap_deg default
  EXPECT_NEAR(-out.comp_rad, 1 * kDeg - walked + overlap, 1e-9);
  // The drive is asked for twice the jump until the motor gets there.
  EXPECT_NEAR(out.theta_cmd_rad - s.theta_cmd_rad, out.comp_rad, 1e-12);
  for (int i = 0; i < 60; ++i) out = c.step(s, {0.95e6, 1e6, s.motor_model_rad});
  EXPECT_EQ(s.boost_rad, 0.0);
  EXPECT_DOUBLE_EQ(out.theta_cmd_rad, s.theta_cmd_rad);
  // Now on the closing flank: the reversal back crosses the whole gap, less what the integral
  // walks before the reversal shows.
  const double at_reversal = s.theta_cmd_rad;
  for (k = 0; k < 200; ++k) {
    out = c.step(s, {1.05e6, 1e6, s.motor_model_rad});  // 50 kPa high: open
    if (out.comp_rad != 0) break;
  }
  ASSERT_LT(k, 200);
  const double walked_back = (s.theta_cmd_rad - out.comp_rad) - at_reversal;
  EXPECT_NEAR(out.comp_rad, 1 * kDeg - walked_back + overlap, 1e-9);
}

// Learning from sigma_r = 0, the tracking compensator's first jump assumes gap_prior_deg: the
// motor is aimed the prior plus the contact overlap past the flank it rested on (no lead: the
// crossing is longer than the model drive's slew x lag, 0.6 deg), and that prior is the gap the
// law reports until a measurement. With a prior of 0 the jump is the overlap past where the
// motor is (no gap ahead is assumed), with the lead of a short traverse.
TEST(Controller, TrackingFirstJumpAssumesThePriorGap) {
  for (const double prior_deg : {0.0, 1.0, 2.5}) {
    auto p = nominal_params(Compensation::adaptive, "tracking");
    p.gap_initial_rad = 0;
    const auto* info = find_compensator("tracking");
    ASSERT_NE(info, nullptr);
    p.compensator_params = hil::param_defaults(info->specs);
    for (std::size_t i = 0; i < info->specs.size(); ++i) {
      if (info->specs[i].key == "gap_prior_deg") p.compensator_params[i] = prior_deg;
    }
    const Controller c(p);
    auto s = c.initial_state(11 * kDeg, 1e6, +1);  // resting on the opening flank
    ControllerOutputs out;
    double motor_rad = s.motor_model_rad;
    int k = 0;
    for (; k < 100; ++k) {
      motor_rad = s.motor_model_rad;
      out = c.step(s, {0.95e6, 1e6, motor_rad});  // 50 kPa low: close
      EXPECT_NEAR(out.gap_est_rad, prior_deg * kDeg, 1e-12);
      if (out.comp_rad != 0) break;
    }
    ASSERT_LT(k, 100) << prior_deg;
    const double overlap = 0.15 * kDeg;  // the tracking compensator's contact_overlap_deg default
    const double target = (prior_deg > 0 ? 11 * kDeg - prior_deg * kDeg : motor_rad) - overlap;
    // A traverse shorter than slew x lag (60 deg/s x 10 ms) carries the rest as a lead.
    const double lead = std::max(0.6 * kDeg - (motor_rad - target), 0.0);
    EXPECT_EQ(lead > 0, prior_deg == 0);
    EXPECT_NEAR(s.theta_cmd_rad, target - lead, 1e-9) << prior_deg;
  }
}

// The tracking compensator's damping (docs/tracking_compensator.md section 5): the command also
// integrates tau LP(dP/dt), so on a pressure ramp of slope r (the filters settled, the dead-band
// of damping_sigmas off) it adds KI dT tau_obs r each period, tau_obs the scheduled chamber time
// constant times the observer's time_constant_scale (0.9); with damping_gain 0 it adds nothing.
TEST(Controller, TrackingDampingAddsKiTimesTauTimesTheSlope) {
  for (const double gain : {0.0, 1.0}) {
    auto p = nominal_params(Compensation::adaptive, "tracking");
    const auto* info = find_compensator("tracking");
    ASSERT_NE(info, nullptr);
    p.compensator_params = hil::param_defaults(info->specs);
    for (std::size_t i = 0; i < info->specs.size(); ++i) {
      if (info->specs[i].key == "damping_gain") p.compensator_params[i] = gain;
      if (info->specs[i].key == "damping_sigmas") p.compensator_params[i] = 0;
    }
    const Controller c(p);
    auto s = c.initial_state(11 * kDeg, 1.05e6, +1);  // opening, the pressure above the reference
    const double slope_pa_s = 50e3;
    ControllerOutputs out;
    for (int k = 0; k < 1500; ++k) out = c.step(s, {1.05e6 + slope_pa_s * k * p.period_s, 1e6, s.motor_model_rad});
    EXPECT_EQ(out.motion_intention, +1);  // no reversal: every period's comp_rad is the damping
    const double tau_obs_s = 0.9 * p.chamber.time_constant_s(1e6, s.volume_m3);
    EXPECT_NEAR(out.comp_rad, gain * out.ki_rad_per_pa_s * p.period_s * tau_obs_s * slope_pa_s,
                0.01 * out.ki_rad_per_pa_s * p.period_s * tau_obs_s * slope_pa_s)
        << gain;
  }
}

TEST(Controller, InvalidParametersAreRejected) {
  auto p = nominal_params(Compensation::constant, "robust");
  p.period_s = 0;
  EXPECT_THROW(Controller{p}, std::invalid_argument);
  p = nominal_params(Compensation::constant, "robust");
  p.gap_known_rad = -0.1;
  EXPECT_THROW(Controller{p}, std::invalid_argument);
  p = nominal_params(Compensation::constant, "robust");
  p.chamber.pressure_exponent = 1.0;
  EXPECT_THROW(Controller{p}, std::invalid_argument);
}

}  // namespace
