// The controller's nominal model against physics.md's numbers.
#include <gtest/gtest.h>

#include "nominal_model.hpp"

using hil::test::nominal_chamber;

TEST(ChamberModel, OperatingPointsOfPhysicsMd) {
  const auto m = nominal_chamber();
  // "1.0 MPa needs At ~ 76.5 mm^2 (theta_V ~ 11.0 deg); 1.5 MPa needs theta_V ~ 5.6 deg"
  EXPECT_NEAR(m.equilibrium_area_m2(1e6) * 1e6, 76.5, 0.3);
  EXPECT_NEAR(m.valve_angle_rad(1e6) * 180 / M_PI, 11.0, 0.1);
  EXPECT_NEAR(m.valve_angle_rad(1.5e6) * 180 / M_PI, 5.6, 0.1);
  // "Chamber time constant near 1 MPa ~ 0.1 s"
  EXPECT_NEAR(m.time_constant_s(1e6, 2e-3), 0.1026, 0.002);
}

TEST(ChamberModel, KiScheduleIs74DegPerMpaSecondAt1MpaAnd2L) {
  hil::ctl::Controller c(hil::test::nominal_params(hil::ctl::Compensation::none, "robust"));
  const double ki_deg_per_mpa_s = c.ki_rad_per_pa_s(1e6, 2e-3) * 180 / M_PI * 1e6;
  EXPECT_NEAR(ki_deg_per_mpa_s, 74, 1.0);  // physics.md: "~ 74 deg/(MPa s) at 1 MPa, 2 L"
  // More volume -> slower chamber -> smaller gain; higher pressure -> stronger plant -> smaller gain.
  EXPECT_LT(c.ki_rad_per_pa_s(1e6, 3e-3), c.ki_rad_per_pa_s(1e6, 2e-3));
  EXPECT_LT(c.ki_rad_per_pa_s(1.5e6, 2e-3), c.ki_rad_per_pa_s(1e6, 2e-3));
}

TEST(ChamberModel, InverseChamberEquationRecoversTheThroat) {
  const auto m = nominal_chamber();
  // At rest the inverse gives the equilibrium area; a rising pressure means less outflow.
  EXPECT_NEAR(m.throat_area_m2(1.2e6, 0, 2e-3), m.equilibrium_area_m2(1.2e6), 1e-12);
  EXPECT_LT(m.throat_area_m2(1.2e6, 1e6, 2e-3), m.equilibrium_area_m2(1.2e6));
  // Against the forward equation: pick At, compute dP/dt, invert.
  const double p = 1.3e6, v = 2.5e-3, at = 70e-6;
  const double mgen = 1700 * 0.01 * m.burn_coeff_si * std::pow(p, 0.35);
  const double dpdt = 352836 / v * (mgen - p * at / 900) - p / v * (mgen / 1700);
  EXPECT_NEAR(m.throat_area_m2(p, dpdt, v), at, 1e-12);
  EXPECT_NEAR(m.angle_for_area_rad(90e-6), 15 * M_PI / 180, 1e-12);
  EXPECT_NEAR(m.angle_for_area_rad(10e-6), 0, 1e-12);  // clamped at the stop
}
