// The paper's observer is equations (3), (4), (7) and (10), exactly.
#include <gtest/gtest.h>

#include "hil/ctl/observer.hpp"

using hil::ctl::ObserverInputs;
using hil::ctl::PaperObserver;

namespace {

ObserverInputs in(double cmd_step, double p) { return {cmd_step, 0, p, 0, 0.1, 2e-3, 0}; }

TEST(PaperObserver, MotionIntentionIsTheSignOfTheCommandChange) {
  PaperObserver o;
  auto s = o.initial_state(1, 1e6);
  EXPECT_EQ(o.step(s, in(+1e-6, 1e6)).intention, 1);
  EXPECT_EQ(o.step(s, in(-1e-6, 1e6)).intention, -1);
  EXPECT_EQ(o.step(s, in(0.0, 1e6)).intention, 0);
}

TEST(PaperObserver, TouchStateFollowsEquation4) {
  PaperObserver o;
  // From +1, motion intention -1 -> transition, and eq. (7) owes -sigma.
  auto s = o.initial_state(1, 1e6);
  auto out = o.step(s, in(-1e-6, 1e6));
  EXPECT_EQ(out.touch, 0);
  EXPECT_EQ(out.kick, -1);
  // In transition: pressure up -> valve being closed -> -1; no jump leaving transition.
  out = o.step(s, in(-1e-6, 1e6 + 10));
  EXPECT_EQ(out.touch, -1);
  EXPECT_EQ(out.kick, 0);
  // From -1, intention +1 -> transition, eq. (7) owes +sigma; pressure down -> +1.
  out = o.step(s, in(+1e-6, 1e6 + 10));
  EXPECT_EQ(out.touch, 0);
  EXPECT_EQ(out.kick, +1);
  out = o.step(s, in(+1e-6, 1e6));
  EXPECT_EQ(out.touch, +1);
  // Otherwise the state holds: same direction, or no pressure change in transition.
  out = o.step(s, in(+1e-6, 1e6 - 50));
  EXPECT_EQ(out.touch, +1);
  s = o.initial_state(0, 1e6);
  out = o.step(s, in(+1e-6, 1e6));
  EXPECT_EQ(out.touch, 0);
}

TEST(PaperObserver, AdaptiveIncrementIsCommandTravelInTransition) {
  PaperObserver o;
  auto s = o.initial_state(1, 1e6);
  EXPECT_DOUBLE_EQ(o.step(s, in(-2e-6, 1e6)).transition_travel_rad, 2e-6);     // entered transition
  EXPECT_DOUBLE_EQ(o.step(s, in(-3e-6, 1e6)).transition_travel_rad, 3e-6);     // still in it
  EXPECT_DOUBLE_EQ(o.step(s, in(-4e-6, 1e6 + 1)).transition_travel_rad, 0.0);  // touch again
}

}  // namespace
