// The physics kernels against closed forms: the burn law's unit conversion, the chamber equation
// at equilibrium and solved for the throat area, the servo's exact lag and its rate limit, and
// the play operator's hysteresis, and P^n near an anchor against pow and Taylor's remainder.
#include "hil/physics.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace {

using hil::physics::GasGenerator;

// The nominal gas generator of physics.md (a = 5 mm/s at 1 MPa, n = 0.35).
GasGenerator nominal() {
  GasGenerator g;
  g.propellant_density_kg_m3 = 1750;
  g.pressure_exponent = 0.35;
  g.burn_coeff_si = hil::physics::burn_coeff_si(5.0, g.pressure_exponent);
  g.burning_area_m2 = 0.0123;
  g.cstar_m_s = 1380;
  g.rtc_m2_s2 = 1.9e6;
  g.volume_growth = 1;
  return g;
}

TEST(Physics, BurnCoefficientGivesTheRateAtOneMegapascalAndItsPowerLaw) {
  const double a_si = hil::physics::burn_coeff_si(5.0, 0.35);
  EXPECT_NEAR(a_si * std::pow(1e6, 0.35), 5e-3, 1e-15);                        // 5 mm/s at 1 MPa
  EXPECT_NEAR(a_si * std::pow(2e6, 0.35), 5e-3 * std::pow(2.0, 0.35), 1e-15);  // r ~ P^n
}

TEST(Physics, AtTheEquilibriumAreaThePressureHoldsStill) {
  const GasGenerator g = nominal();
  const double v_m3 = 2e-3;
  for (double p_pa : {0.5e6, 1e6, 2e6}) {
    const double at = g.equilibrium_area_m2(p_pa);
    const auto r = g.rates(p_pa, std::pow(p_pa, g.pressure_exponent), v_m3, at);
    EXPECT_NEAR(r.dp_pa_s, 0.0, 1e-9 * p_pa) << p_pa;
    // The outflow is short of the generation by exactly the gas that fills the freed volume.
    EXPECT_NEAR(r.mdot_gen_kg_s - r.mdot_out_kg_s, p_pa * r.dv_m3_s / g.rtc_m2_s2, 1e-12) << p_pa;
    // The fixed point for that area returns the same pressure.
    double p = 1e6;
    for (int i = 0; i < 60; ++i) p = g.equilibrium_pressure_step_pa(p, at);
    EXPECT_NEAR(p, p_pa, 1e-9 * p_pa);
  }
}

TEST(Physics, TheThroatAreaSolvedForGivesTheRequestedPressureRate) {
  const GasGenerator g = nominal();
  for (double dpdt : {-2e6, 0.0, 3e6}) {
    const double p_pa = 1.2e6, v_m3 = 1.5e-3;
    const double at = g.throat_area_m2(p_pa, dpdt, v_m3);
    const auto r = g.rates(p_pa, std::pow(p_pa, g.pressure_exponent), v_m3, at);
    EXPECT_NEAR(r.dp_pa_s, dpdt, 1e-6 * 3e6) << dpdt;
  }
  // A falling pressure needs a wider throat than a steady one.
  EXPECT_GT(g.throat_area_m2(1e6, -1e6, 2e-3), g.equilibrium_area_m2(1e6));
}

TEST(Physics, TheServoLagIsExactWhateverTheStepAndTheRateLimitCaps) {
  const double tau_s = 0.02, cmd = 1.0;
  // Ten steps of 1 ms and one of 10 ms land on the same exponential.
  double a = 0;
  for (int i = 0; i < 10; ++i) a = hil::physics::servo_step_rad(a, cmd, hil::physics::servo_keep(1e-3, tau_s), 1e9);
  const double b = hil::physics::servo_step_rad(0, cmd, hil::physics::servo_keep(1e-2, tau_s), 1e9);
  EXPECT_NEAR(a, 1 - std::exp(-0.01 / tau_s), 1e-12);
  EXPECT_NEAR(b, a, 1e-12);
  // The slew limit caps the move, in both directions.
  EXPECT_DOUBLE_EQ(hil::physics::servo_step_rad(0, 1.0, 0.0, 0.01), 0.01);
  EXPECT_DOUBLE_EQ(hil::physics::servo_step_rad(0, -1.0, 0.0, 0.01), -0.01);
}

// Taylor's remainder of the fourth-order expansion: the fifth term, C5 d^5 with
// C5 = n(n-1)(n-2)(n-3)(n-4)/120 (0.0303 for n = 0.35), at most 3.03e-12 for d <= 1 %; the
// derivatives lose one and two orders: 5 C5 d^4 / n and 10 C5 d^3 / (n(n-1)/2).
TEST(Physics, PowNearFollowsPowWithinTaylorsRemainder) {
  const double n = 0.35;
  const double c5 = n * (n - 1) * (n - 2) * (n - 3) * (n - 4) / 120;
  const double band = hil::physics::PowNear::kBand;
  hil::physics::PowNear near;
  double p = 1e6;
  int anchors = 0;
  for (int k = 0; k < 20000; ++k) {
    p *= 1 + 0.001 * std::sin(k * 0.01);  // up to 0.1 % a call, back and forth over 1.0-1.22 MPa
    const double before = near.anchor;
    const auto local = near.at(p, n);
    if (near.anchor != before) ++anchors;
    const double d = std::abs(p - near.anchor) / near.anchor;
    ASSERT_LE(d, band);
    const double exact = std::pow(p, n);
    EXPECT_NEAR(local.value / exact, 1.0, std::abs(c5) * std::pow(band, 5) * 1.01 + 1e-15) << p;
    EXPECT_NEAR(local.slope / (n * exact / p), 1.0, 5 * std::abs(c5) * std::pow(band, 4) / n * 1.01 + 1e-15) << p;
    EXPECT_NEAR(local.curve / (n * (n - 1) / 2 * exact / (p * p)), 1.0,
                10 * std::abs(c5) * std::pow(band, 3) / std::abs(n * (n - 1) / 2) * 1.01 + 1e-15)
        << p;
    EXPECT_NEAR(near.value(p, n) / exact, 1.0, std::abs(c5) * std::pow(band, 5) * 1.01 + 1e-15) << p;
  }
  // The anchor moved, but far less often than the pressure did.
  EXPECT_GT(anchors, 10);
  EXPECT_LT(anchors, 4000);
  // A jump beyond the band moves the anchor to the pressure itself: the value is pow's.
  EXPECT_EQ(near.value(3.7e6, n), std::pow(3.7e6, n));
}

TEST(Physics, ThePlayOperatorHoldsInsideTheGapAndFollowsTheFlankItTouches) {
  const double half = 0.5;
  double valve = 0;
  // The driver moves up: nothing until it has crossed half the gap, then the valve follows it.
  for (double motor : {0.2, 0.5}) valve = hil::physics::play_rad(valve, motor, half);
  EXPECT_DOUBLE_EQ(valve, 0.0);
  valve = hil::physics::play_rad(valve, 1.5, half);
  EXPECT_DOUBLE_EQ(valve, 1.0);
  // Reversing: the valve waits while the driver crosses the whole gap, then follows below it.
  for (double motor : {1.2, 0.5}) valve = hil::physics::play_rad(valve, motor, half);
  EXPECT_DOUBLE_EQ(valve, 1.0);
  valve = hil::physics::play_rad(valve, 0.2, half);
  EXPECT_DOUBLE_EQ(valve, 0.7);
}

}  // namespace
