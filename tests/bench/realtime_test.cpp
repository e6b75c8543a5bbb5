// The loop's period is on the real-time path: with every injection, trip and event in play it
// must not allocate.
#include <gtest/gtest.h>

#include "alloc_counter.hpp"
#include "hil/units.hpp"
#include "loop_fixture.hpp"

using namespace hil::bench;

TEST(RunLoopRealtime, PeriodDoesNotAllocate) {
  SafetyConfig safety;
  safety.safe_mode = SafeMode::angle;
  safety.safe_angle_rad = 0.1;
  safety.safe_hold_s = 0.5;
  safety.rate_limit_rad_s = 2.0;     // so the limiter works too
  safety.following_error_rad = 0.5;  // watched, never beyond (the rate limit keeps the drive close)
  safety.following_error_s = 0.1;
  LoopConfig cfg;
  cfg.overrun_policy = OverrunPolicy::abort;
  hil::test::LoopHarness h(hil::test::short_campaign(8.0), "adaptive", safety, cfg, 1024);
  std::vector<TelemetryRecord> rows(1024);
  std::vector<LoopEvent> events(1024);
  using K = LoopRequest::Kind;
  const LoopRequest script[] = {
      {.kind = K::set_gap, .value = hil::units::deg_to_rad(2.0)},
      {.kind = K::sensor_fault, .sensor = SensorFault::noise, .value = 3e3, .duration_s = 0.3},
      {.kind = K::sensor_fault, .sensor = SensorFault::bias, .value = 1e3, .duration_s = 0.3},
      {.kind = K::sensor_fault, .sensor = SensorFault::stuck, .duration_s = 0.2},
      {.kind = K::sensor_fault, .sensor = SensorFault::dropout, .duration_s = 0.001},
      {.kind = K::drive_fault, .duration_s = 0.2},
      {.kind = K::programme_gap},
      {.kind = K::drive_fault, .duration_s = 0},
      {.kind = K::clear_faults},
      {.kind = K::rig_fault, .on = true},  // the watchdog trips: the safe state runs too
  };
  const long before = hil::test::allocations();
  std::size_t next = 0;
  bool running = true;
  for (long k = 0; running; ++k) {
    if (k % 600 == 300 && next < std::size(script)) h.requests.try_push(script[next++]);
    running = h.step(k % 997 == 0 ? std::chrono::microseconds(1500) : std::chrono::microseconds(20));
    h.telemetry.pop(rows.data(), rows.size());
    h.events.pop(events.data(), events.size());
    (void)h.loop->snapshot();
  }
  EXPECT_EQ(hil::test::allocations() - before, 0);
  EXPECT_EQ(next, std::size(script));
  EXPECT_EQ(h.loop->trip(), Trip::watchdog);
  EXPECT_GT(h.loop->overruns(), 0);
}
