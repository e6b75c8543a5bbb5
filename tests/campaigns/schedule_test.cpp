#include "hil/bench/rt/schedule.hpp"

#include <gtest/gtest.h>

#include <cstring>

#include "hil/plant/rng.hpp"

using hil::bench::Schedule;

TEST(Schedule, StepsRampsAndSines) {
  Schedule s(1.0);
  s.add(2.5, 1.0);
  s.add(2.5, 1.5);  // a step
  s.add(5.0, 1.5);
  s.add(6.0, 1.0);  // a ramp down over 1 s
  EXPECT_DOUBLE_EQ(s.at(0.0), 1.0);
  EXPECT_DOUBLE_EQ(s.at(2.4999), 1.0);
  EXPECT_DOUBLE_EQ(s.at(2.5), 1.5);
  EXPECT_DOUBLE_EQ(s.at(5.5), 1.25);
  EXPECT_DOUBLE_EQ(s.at(99), 1.0);
  s.add_sine({1.0, 2.0, 0.1, 0.4});
  EXPECT_NEAR(s.at(1.1), 1.1, 1e-12);  // a quarter period in
  EXPECT_NEAR(s.at(2.2), 1.0, 1e-12);  // the sine has ended
}

TEST(Schedule, CursorAgreesWithRandomAccess) {
  Schedule s(0.0);
  for (int i = 0; i < 50; ++i) s.add(0.3 * i, (i % 3) * 0.7), s.add(0.3 * i + 0.1, (i % 5) * 0.2);
  Schedule::Cursor c;
  for (int k = 0; k < 16000; ++k) ASSERT_DOUBLE_EQ(s.at(k * 1e-3, c), s.at(k * 1e-3)) << k;
}

// The cursor keeps the level it last found (a step profile between steps): the same bits as a
// search, on levels, ramps, jumps, a sine window, times going back and times out of range.
TEST(Schedule, CursorLevelsGiveTheSearchedBits) {
  Schedule steps(-0.0);  // -0.0 + 0.0 is +0.0: the kept level must be the returned value
  steps.add(1, -0.0), steps.add(1, 2.0), steps.add(2, 2.0), steps.add(3, 4.0), steps.add(3, 1.0), steps.add(5, 1.0);
  Schedule with_sine = steps;
  with_sine.add_sine({1.5, 2.5, 0.3, 0.4});
  hil::plant::Rng rng(3);
  for (const Schedule* s : {&steps, &with_sine}) {
    Schedule::Cursor c;
    // From before the first breakpoint to past the last, 0.5 ms a call on average, and one call
    // in 2 000 going back up to 1 s (about 16 of them on the way).
    long calls = 0, back = 0;
    for (double t = -1; t < 7; ++calls) {
      const bool jump_back = rng.uniform() < 0.0005;
      back += jump_back;
      t += jump_back ? -rng.uniform() : 1e-3 * rng.uniform();
      const double a = s->at(t, c), b = s->at(t);
      ASSERT_EQ(std::memcmp(&a, &b, sizeof a), 0) << "t=" << t << " cursor " << a << " search " << b;
    }
    EXPECT_GE(back, 5) << "the walk went back in time too seldom to test it (" << calls << " calls)";
  }
}

TEST(Schedule, ReversalsAndMoves) {
  Schedule square(1.0);
  for (int i = 1; i <= 6; ++i) {
    square.add(2.5 * i, i % 2 ? 1.0 : 1.5);
    square.add(2.5 * i, i % 2 ? 1.5 : 1.0);
  }
  const auto r = hil::bench::reversal_times(square, 18, 1e-3, 1e3 * 1e-6);
  ASSERT_EQ(r.size(), 6u);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(r[i], 2.5 * (i + 1), 1.5e-3);
  EXPECT_EQ(hil::bench::move_count(square, 18, 1e-3), 6);
  // Two steps up, then one down: three moves, two reversals.
  Schedule stairs(1.0);
  stairs.add(1, 1.0), stairs.add(1, 1.2), stairs.add(2, 1.2), stairs.add(2, 1.4), stairs.add(3, 1.4), stairs.add(3, 1.1);
  EXPECT_EQ(hil::bench::reversal_times(stairs, 4, 1e-3, 1e-6).size(), 2u);
  EXPECT_EQ(hil::bench::move_count(stairs, 4, 1e-3), 3);
}
