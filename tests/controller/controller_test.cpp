// The controller's step: real-time safe, and the jumps it makes.
#include <gtest/gtest.h>

#include "alloc_counter.hpp"
#include "nominal_model.hpp"

using namespace hil::ctl;
using hil::test::nominal_params;

namespace {

constexpr double kDeg = M_PI / 180;

static_assert(noexcept(std::declval<const Controller&>().step(std::declval<ControllerState&>(), ControllerInputs{})));

TEST(Controller, StepAllocatesNothing) {
  for (auto obs : {ObserverKind::paper, ObserverKind::robust}) {
    const Controller c(nominal_params(Compensation::adaptive, obs));
    auto s = c.initial_state(11 * kDeg, 1e6, +1);
    const long before = hil::test::allocations();
    for (int k = 0; k < 20000; ++k) {
      const double p = 1e6 + 5e4 * std::sin(k * 1e-3 * 3) + (k % 7) * 300.0;
      c.step(s, {p, 1e6, s.theta_cmd_rad});
    }
    EXPECT_EQ(hil::test::allocations() - before, 0);
  }
}

TEST(Controller, IntegralLawHasTheStabilisingSign) {
  const Controller c(nominal_params(Compensation::none, ObserverKind::robust));
  auto s = c.initial_state(11 * kDeg, 1e6, +1);
  const double ki = c.ki_rad_per_pa_s(1e6, 2e-3);
  const auto out = c.step(s, {1.01e6, 1e6, 11 * kDeg});
  // Pressure 10 kPa too high -> open the valve by KI dT dPg.
  EXPECT_NEAR(out.theta_cmd_rad - 11 * kDeg, ki * 1e-3 * 1e4, 1e-12);
}

TEST(Controller, PaperConstantJumpsExactlySigma) {
  const Controller c(nominal_params(Compensation::constant, ObserverKind::paper));
  auto s = c.initial_state(11 * kDeg, 1e6, +1);
  const auto out = c.step(s, {0.99e6, 1e6, 11 * kDeg});  // too low: close, leaving the + flank
  EXPECT_NEAR(out.comp_rad, -1 * kDeg, 1e-15);
  EXPECT_EQ(out.touch_state, 0);
}

TEST(Controller, RobustJumpCrossesToTheFlankAheadAndBoostsTheCrossing) {
  auto p = nominal_params(Compensation::constant, ObserverKind::robust);
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
  EXPECT_NEAR(-out.comp_rad, 1 * kDeg - walked + p.contact_overlap_rad, 1e-9);
  EXPECT_NEAR(s.gap_pos_rad, -0.5 * kDeg, 1e-12);  // now on the closing flank
  // The drive is asked for twice the jump until the motor gets there.
  EXPECT_NEAR(out.theta_cmd_rad - s.theta_cmd_rad, out.comp_rad, 1e-12);
  for (int i = 0; i < 60; ++i) out = c.step(s, {0.95e6, 1e6, s.motor_model_rad});
  EXPECT_EQ(s.boost_rad, 0.0);
  EXPECT_DOUBLE_EQ(out.theta_cmd_rad, s.theta_cmd_rad);
}

TEST(Controller, InvalidParametersAreRejected) {
  auto p = nominal_params(Compensation::constant, ObserverKind::robust);
  p.period_s = 0;
  EXPECT_THROW(Controller{p}, std::invalid_argument);
  p = nominal_params(Compensation::constant, ObserverKind::robust);
  p.gap_known_rad = -0.1;
  EXPECT_THROW(Controller{p}, std::invalid_argument);
  p = nominal_params(Compensation::constant, ObserverKind::robust);
  p.chamber.pressure_exponent = 1.0;
  EXPECT_THROW(Controller{p}, std::invalid_argument);
}

}  // namespace
