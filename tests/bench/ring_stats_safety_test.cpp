// The lock-free ring, the latency histogram and the interlocks' arithmetic.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <thread>
#include <vector>

#include "hil/bench/rt/loop_stats.hpp"
#include "hil/bench/rt/rt_thread.hpp"
#include "hil/bench/rt/safety.hpp"
#include "hil/bench/rt/spsc_ring.hpp"
#include "hil/config.hpp"

using namespace hil::bench;

TEST(SpscRing, FullRingRefusesAndKeepsOrder) {
  SpscRing<int> ring(5);
  EXPECT_EQ(ring.capacity(), 8u);
  for (int i = 0; i < 8; ++i) EXPECT_TRUE(ring.try_push(i));
  EXPECT_FALSE(ring.try_push(99));
  int out[16];
  ASSERT_EQ(ring.pop(out, 3), 3u);
  EXPECT_EQ(out[0], 0);
  EXPECT_EQ(out[2], 2);
  EXPECT_TRUE(ring.try_push(8));
  ASSERT_EQ(ring.pop(out, 16), 6u);
  EXPECT_EQ(out[5], 8);
  EXPECT_EQ(ring.size(), 0u);
}

TEST(SpscRing, TwoThreadsPassEveryValueInOrder) {
  SpscRing<long> ring(1024);
  constexpr long kCount = 2'000'000;
  std::thread producer([&] {
    for (long i = 0; i < kCount;) {
      if (ring.try_push(i)) ++i;
    }
  });
  long expected = 0;
  long buf[256];
  while (expected < kCount) {
    const std::size_t n = ring.pop(buf, 256);
    for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(buf[i], expected++);
  }
  producer.join();
}

// consume() reads the values where they lie, in order, and frees exactly the slots it handed out.
TEST(SpscRing, ConsumeHandsOutInOrderAndFreesTheSlots) {
  SpscRing<int> ring(4);
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(ring.try_push(i));
  EXPECT_FALSE(ring.try_push(99));
  std::vector<int> seen;
  EXPECT_EQ(ring.consume(3, [&](const int& v) { seen.push_back(v); }), 3u);
  EXPECT_EQ(seen, (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(ring.size(), 1u);
  for (int i = 4; i < 7; ++i) EXPECT_TRUE(ring.try_push(i));  // the three freed slots, wrapping
  EXPECT_FALSE(ring.try_push(99));
  EXPECT_EQ(ring.consume(16, [&](const int& v) { seen.push_back(v); }), 4u);
  EXPECT_EQ(seen, (std::vector<int>{0, 1, 2, 3, 4, 5, 6}));
  EXPECT_EQ(ring.consume(16, [&](const int&) { ADD_FAILURE() << "an empty ring handed out a value"; }), 0u);
}

// claim() lends the next slot to be written in place: the consumer sees nothing of it before
// publish(), the same slot comes back until then, and a full ring lends none.
TEST(SpscRing, AClaimedSlotIsInvisibleUntilPublished) {
  SpscRing<int> ring(2);
  int* slot = ring.claim();
  ASSERT_NE(slot, nullptr);
  *slot = 7;
  EXPECT_EQ(ring.size(), 0u);
  EXPECT_EQ(ring.consume(16, [](const int&) { ADD_FAILURE() << "an unpublished value was handed out"; }), 0u);
  EXPECT_EQ(ring.claim(), slot);
  ring.publish();
  ASSERT_TRUE(ring.try_push(8));
  EXPECT_EQ(ring.claim(), nullptr);  // full
  std::vector<int> seen;
  EXPECT_EQ(ring.consume(1, [&](const int& v) { seen.push_back(v); }), 1u);
  int* again = ring.claim();  // the freed slot, wrapping
  EXPECT_EQ(again, slot);
  *again = 9;
  ring.publish();
  EXPECT_EQ(ring.consume(16, [&](const int& v) { seen.push_back(v); }), 2u);
  EXPECT_EQ(seen, (std::vector<int>{7, 8, 9}));
}

TEST(LatencyHistogram, PercentilesWithinTheBucketWidth) {
  LatencyHistogram h;
  std::mt19937_64 rng(3);
  std::vector<long> ns;
  std::lognormal_distribution<double> d(std::log(20000.0), 0.6);
  for (int i = 0; i < 200000; ++i) ns.push_back(static_cast<long>(d(rng)));
  for (long v : ns) h.add(std::chrono::nanoseconds(v));
  std::sort(ns.begin(), ns.end());
  const TimingSummary s = h.summary();
  auto exact = [&](double q) { return ns[static_cast<std::size_t>(std::ceil(q * ns.size())) - 1] / 1e3; };
  EXPECT_EQ(s.count, 200000);
  EXPECT_NEAR(s.p50_us, exact(0.5), exact(0.5) * 0.016);
  EXPECT_NEAR(s.p99_us, exact(0.99), exact(0.99) * 0.016);
  EXPECT_NEAR(s.p999_us, exact(0.999), exact(0.999) * 0.016);
  EXPECT_DOUBLE_EQ(s.max_us, ns.back() / 1e3);
  EXPECT_DOUBLE_EQ(s.min_us, ns.front() / 1e3);
  EXPECT_GE(s.p50_us, exact(0.5));  // upper edges: never optimistic
}

TEST(LatencyHistogram, SmallAndHugeValues) {
  LatencyHistogram h;
  h.add(std::chrono::nanoseconds(-5));
  h.add(std::chrono::nanoseconds(3));
  h.add(std::chrono::seconds(100));
  const TimingSummary s = h.summary();
  EXPECT_EQ(s.count, 3);
  EXPECT_EQ(s.min_us, 0);
  EXPECT_DOUBLE_EQ(s.max_us, 100e6);
  EXPECT_DOUBLE_EQ(s.p50_us, 0.003);
}

TEST(Safety, WatchdogCountsMissesInARow) {
  SafetyConfig c;
  c.watchdog_misses = 3;
  Safety s(c);
  double v, l;
  EXPECT_EQ(s.check(true, false, 0, v, l), Trip::none);
  EXPECT_EQ(s.check(true, false, 0, v, l), Trip::none);
  EXPECT_EQ(s.check(false, false, 1e6, v, l), Trip::none);  // an answer resets the count
  EXPECT_EQ(s.check(true, false, 0, v, l), Trip::none);
  EXPECT_EQ(s.check(true, false, 0, v, l), Trip::none);
  EXPECT_EQ(s.check(true, false, 0, v, l), Trip::watchdog);
  EXPECT_EQ(v, 3);
}

TEST(Safety, PressureThresholdsDebounce) {
  SafetyConfig c;
  c.p_max_pa = 2e6;
  c.p_min_pa = 0.5e6;
  c.pressure_debounce = 2;
  Safety s(c);
  double v, l;
  EXPECT_EQ(s.check(false, false, 2.1e6, v, l), Trip::none);
  EXPECT_EQ(s.check(false, false, 1.0e6, v, l), Trip::none);
  EXPECT_EQ(s.check(false, false, 2.1e6, v, l), Trip::none);
  EXPECT_EQ(s.check(false, false, 2.2e6, v, l), Trip::overpressure);
  EXPECT_EQ(l, 2e6);
  Safety u(c);
  EXPECT_EQ(u.check(false, false, 0.4e6, v, l), Trip::none);
  EXPECT_EQ(u.check(false, false, 0.3e6, v, l), Trip::underpressure);
  EXPECT_EQ(u.check(false, true, 1e6, v, l), Trip::rig_fault);
}

TEST(Safety, LimitsAndSafeCommand) {
  SafetyConfig c;
  c.cmd_min_rad = -0.1;
  c.cmd_max_rad = 0.5;
  c.rate_limit_rad_s = 10;  // 0.01 rad per 1 ms
  c.safe_mode = SafeMode::angle;
  c.safe_angle_rad = 0.2;
  c.safe_rate_rad_s = 1;
  Safety s(c);
  bool limited = false;
  EXPECT_DOUBLE_EQ(s.limit(0.305, 0.3, 1e-3, limited), 0.305);
  EXPECT_FALSE(limited);
  EXPECT_DOUBLE_EQ(s.limit(0.6, 0.495, 1e-3, limited), 0.5);
  EXPECT_TRUE(limited);
  EXPECT_DOUBLE_EQ(s.limit(0.4, 0.3, 1e-3, limited), 0.31);
  EXPECT_DOUBLE_EQ(s.limit(std::nan(""), 0.3, 1e-3, limited), 0.3);
  EXPECT_TRUE(limited);
  EXPECT_DOUBLE_EQ(s.safe_command(0.3, 1e-3), 0.299);
  EXPECT_DOUBLE_EQ(s.safe_command(0.2005, 1e-3), 0.2);
}

TEST(Safety, ConfigErrorsNameTheKey) {
  const auto node = hil::cfg::Node::load_string(
      "cmd_min_deg: -5\ncmd_max_deg: 35\nrate_limit_deg_s: 100\np_max_mpa: 0.1\np_min_mpa: 0.2\n", "rig.yaml");
  try {
    SafetyConfig::from_yaml(node);
    FAIL();
  } catch (const hil::cfg::Error& e) {
    EXPECT_NE(std::string(e.what()).find("rig.yaml:4"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("p_max_mpa"), std::string::npos) << e.what();
  }
  const auto typo = hil::cfg::Node::load_string(
      "cmd_min_deg: -5\ncmd_max_deg: 35\nrate_limit_deg_s: 100\np_max_mpa: 2\np_min_mpa: 0.2\nwatchdog_mises: 3\n", "rig.yaml");
  EXPECT_THROW(SafetyConfig::from_yaml(typo), hil::cfg::Error);
}

// The following error trips once it has been beyond its limit for the configured time in a row
// (50 periods of 1 ms here: the 50th, not the 49th), with the signed error and the limit; a
// period back within the limit starts the count again; a position the rig does not measure is
// not checked; and it is off unless set (the default and none()).
TEST(Safety, FollowingErrorTripsAfterItsTimeBeyondTheLimit) {
  SafetyConfig c;
  EXPECT_FALSE(c.watches_following());
  EXPECT_FALSE(SafetyConfig::none().watches_following());
  c.following_error_rad = 0.015625;  // binary fractions: "on the limit" is exactly on it
  c.following_error_s = 0.050;
  ASSERT_TRUE(c.watches_following());
  Safety s(c);
  double v = 0, l = 0;
  for (int k = 1; k <= 30; ++k) ASSERT_EQ(s.follow(0.5, 0.5 - 0.016, 1e-3, v, l), Trip::none) << k;
  EXPECT_EQ(s.follow(0.5, 0.5 + 0.015625, 1e-3, v, l), Trip::none);  // on the limit is within: the count starts again
  EXPECT_EQ(s.follow(0.5, std::nan(""), 1e-3, v, l), Trip::none);
  for (int k = 1; k <= 49; ++k) ASSERT_EQ(s.follow(0.5, 0.546875, 1e-3, v, l), Trip::none) << k;
  EXPECT_EQ(s.follow(0.5, 0.546875, 1e-3, v, l), Trip::following_error);
  EXPECT_EQ(v, 0.046875);
  EXPECT_EQ(l, 0.015625);
  EXPECT_EQ(to_string(Trip::following_error), "following error");
  // A time of 0: the first period beyond trips.
  c.following_error_s = 0;
  Safety at_once(c);
  EXPECT_EQ(at_once.follow(0.5, 0.5, 1e-3, v, l), Trip::none);
  EXPECT_EQ(at_once.follow(0.5, 0.453125, 1e-3, v, l), Trip::following_error);
  EXPECT_EQ(v, -0.046875);
}

TEST(Safety, FollowingErrorFromTheRigFileAndItsErrors) {
  const std::string base = "cmd_min_deg: -5\ncmd_max_deg: 35\nrate_limit_deg_s: 100\np_max_mpa: 2\np_min_mpa: 0.2\n";
  const SafetyConfig c =
      SafetyConfig::from_yaml(hil::cfg::Node::load_string(base + "following_error: {max_deg: 2, time_ms: 50}\n", "rig.yaml"));
  EXPECT_DOUBLE_EQ(c.following_error_rad, 2 * 0.017453292519943295);
  EXPECT_DOUBLE_EQ(c.following_error_s, 0.05);
  EXPECT_FALSE(SafetyConfig::from_yaml(hil::cfg::Node::load_string(base, "rig.yaml")).watches_following());
  const std::pair<std::string, std::string> bad[] = {
      {"following_error: {max_deg: 0, time_ms: 50}", "rig.yaml:6:19: following_error.max_deg"},
      {"following_error: {max_deg: .nan, time_ms: 50}", "rig.yaml:6:19: following_error.max_deg"},
      {"following_error: {max_deg: 2, time_ms: -1}", "rig.yaml:6:"},
      {"following_error: {max_deg: 2, time_ms: 4294967346}", "rig.yaml:6:"},
      {"following_error: {max_deg: 2}", "time_ms"},
      {"following_error: {max_deg: 2, time_ms: 50, window: 3}", "window"},
      {"following_error: 2", "rig.yaml:6"},
  };
  for (const auto& [text, where] : bad) {
    try {
      SafetyConfig::from_yaml(hil::cfg::Node::load_string(base + text + "\n", "rig.yaml"));
      ADD_FAILURE() << text;
    } catch (const hil::cfg::Error& e) {
      EXPECT_NE(std::string(e.what()).find(where), std::string::npos) << text << ": " << e.what();
    }
  }
}

TEST(Pacer, SkipsPassedDeadlinesLikeCyclictest) {
  using namespace std::chrono_literals;
  const Clock::time_point d{1s};
  std::int64_t skipped = -1;
  EXPECT_EQ(next_deadline(d, 1ms, d + 300us, skipped), d + 1ms);  // on time
  EXPECT_EQ(skipped, 0);
  EXPECT_EQ(next_deadline(d, 1ms, d + 1ms, skipped), d + 1ms);  // ends exactly on it: not passed
  EXPECT_EQ(skipped, 0);
  EXPECT_EQ(next_deadline(d, 1ms, d + 1001us, skipped), d + 2ms);  // overran by 1 us: wait for the next
  EXPECT_EQ(skipped, 1);
  EXPECT_EQ(next_deadline(d, 1ms, d + 10500us, skipped), d + 11ms);  // a 10 ms stall: no burst
  EXPECT_EQ(skipped, 10);
}
