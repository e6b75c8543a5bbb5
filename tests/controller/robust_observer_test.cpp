// The robust observer on synthetic signals: quiet under noise, quick on real events.
#include <gtest/gtest.h>

#include <random>

#include "hil/ctl/observer.hpp"
#include "nominal_model.hpp"

using namespace hil::ctl;

namespace {

constexpr double kDt = 1e-3, kTau = 0.1026, kV = 2e-3;

struct Rig {
  RobustObserver obs{RobustObserverParams{}, hil::test::nominal_chamber()};
  RobustObserverState s;
  std::mt19937 rng{42};
  std::normal_distribution<double> noise{0, 2000};  // the nominal transducer
  Rig(int touch, double p0) { s = obs.initial_state(touch, 0.2, p0, 0.2); }
  ObserverOutputs step(double p_true, double p_ref, double motor = 0.2) {
    const double p = p_true + noise(rng);
    const double ki = 1.29e-6;  // rad/(Pa s), ~74 deg/(MPa s)
    return obs.step(s, {ki * kDt * (p - p_ref), p - p_ref, p, motor, kTau, kV, 0});
  }
};

TEST(RobustObserver, NoiseAtASetpointIsNoReversal) {
  Rig r(+1, 1e6);
  int reversals = 0, touch_changes = 0, last = r.s.touch;
  for (int k = 0; k < 20000; ++k) {  // 20 s holding 1 MPa with 2 kPa of noise
    const auto out = r.step(1e6, 1e6);
    reversals += out.reversed;
    touch_changes += out.touch != last;
    last = out.touch;
  }
  EXPECT_EQ(reversals, 0);
  EXPECT_EQ(touch_changes, 0);
}

TEST(RobustObserver, RealReversalIsSeenWithinMilliseconds) {
  // Closing (error negative: pressure too low); the pressure then rises through the reference
  // at 0.5 MPa/s, so the integrator turns to opening.
  Rig r(-1, 1e6);
  r.s.intention = -1;
  int seen_at = -1;
  for (int k = 0; k < 200; ++k) {
    const double p = 1e6 - 5e3 + 500.0 * k;  // -5 kPa, rising 0.5 MPa/s
    if (r.step(p, 1e6).reversed && seen_at < 0) seen_at = k;
  }
  ASSERT_GE(seen_at, 0);
  // The error crosses zero at k = 10; the filtered error passes 8 sigma a few ms later.
  EXPECT_GT(seen_at, 10);
  EXPECT_LT(seen_at, 40);
  EXPECT_EQ(r.s.intention, +1);
  EXPECT_EQ(r.s.touch, 0);  // left the flank: in transition
}

TEST(RobustObserver, ChamberStillRelaxingIsNotContact) {
  // After a reversal the valve holds while the chamber relaxes toward the held valve's
  // equilibrium (tau ~ 0.1 s): the raw pressure still moves, P_eq does not.
  Rig r(-1, 1.4e6);
  r.s.intention = -1;
  for (int k = 0; k < 20; ++k) r.step(1.4e6 - 2e4 * std::exp(-k * kDt / kTau), 1.45e6);
  // Reverse: the error turns positive, the pressure keeps rising toward 1.40 MPa + relaxation.
  int touch_changes = 0, last = r.s.touch;
  for (int k = 20; k < 3000; ++k) {
    const double p = 1.4e6 - 2e4 * std::exp(-k * kDt / kTau);  // still rising, valve held
    const auto out = r.step(p, 1.37e6);
    touch_changes += out.touch != last;
    last = out.touch;
  }
  EXPECT_EQ(r.s.touch, 0) << "no contact while only the chamber moves";
  EXPECT_LE(touch_changes, 1);  // only the reversal itself
}

TEST(RobustObserver, ValveMotionIsContact) {
  Rig r(-1, 1.2e6);
  r.s.intention = -1;
  for (int k = 0; k < 200; ++k) r.step(1.2e6, 1.2e6);
  // Reverse (pressure above reference), then the valve opens: pressure falls 0.3 MPa/s.
  int contact_at = -1;
  for (int k = 0; k < 1000; ++k) {
    const double p = k < 100 ? 1.2e6 : 1.2e6 - 300.0 * (k - 100);
    r.step(p, 1.19e6);
    if (r.s.touch == +1 && contact_at < 0) contact_at = k;
  }
  ASSERT_GE(contact_at, 0);
  EXPECT_GT(contact_at, 100);  // not before the valve moved
  EXPECT_LT(contact_at, 200);  // but within a few filter time constants
}

TEST(RobustObserver, NoiseThresholdsFollowTheTransducer) {
  RobustObserverParams quiet;
  quiet.pressure_noise_rms_pa = 500;
  RobustObserver a(RobustObserverParams{}, hil::test::nominal_chamber()), b(quiet, hil::test::nominal_chamber());
  EXPECT_NEAR(a.p_eq_noise_pa(kTau) / b.p_eq_noise_pa(kTau), 4.0, 1e-9);
  EXPECT_NEAR(a.intention_threshold_pa() / b.intention_threshold_pa(), 4.0, 1e-9);
  EXPECT_GT(a.p_eq_noise_pa(2 * kTau), a.p_eq_noise_pa(kTau));  // the derivative term grows with tau
}

TEST(RobustObserver, InvalidParametersNameThemselves) {
  RobustObserverParams p;
  p.learn_gain = 0;
  try {
    RobustObserver o(p, hil::test::nominal_chamber());
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("learn_gain"), std::string::npos);
  }
}

}  // namespace
