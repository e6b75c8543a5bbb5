// The recorder writes every row the loop produced, parseable by the strict reader, and the
// events as one JSON object a line.
#include <gtest/gtest.h>

#include <fstream>

#include "hil/bench/rt/recorder.hpp"
#include "hil/bench/server/runner.hpp"
#include "hil/csv_reader.hpp"
#include "loop_fixture.hpp"

using namespace hil::bench;
using namespace std::chrono_literals;

TEST(Recorder, WritesEveryRowAndEvent) {
  hil::test::TempDir dir;
  std::atomic<long> seen{0};
  Recorder rec(
      dir.path(), {{"campaign", "x"}}, 256, [&](const TelemetryRecord&) { ++seen; }, 10ms);
  // More rows than the ring holds: the producer waits for room here (a test, not the loop).
  for (int i = 0; i < 5000; ++i) {
    TelemetryRecord r;
    r.step.t_s = i * 1e-3;
    r.step.p_meas_pa = 1e6 + i;
    r.wake_latency_us = 3.25;
    r.flags = kFlagOverrun;
    while (!rec.telemetry().try_push(r)) std::this_thread::yield();
  }
  ASSERT_TRUE(rec.events().try_push({.period = 7, .t_s = 0.007, .body = event::GapChange{0.04}}));
  ASSERT_TRUE(rec.events().try_push({.t_s = 1.5, .body = event::Tripped{Trip::watchdog, 3, 3}}));
  for (int tries = 0; tries < 400 && rec.events_written() < 2; ++tries) std::this_thread::sleep_for(5ms);
  rec.log({{"kind", "run_start"}, {"source", "bench"}});
  EXPECT_EQ(rec.finish(), "");
  EXPECT_EQ(rec.rows_written(), 5000u);
  EXPECT_EQ(seen.load(), 5000);

  hil::CsvHeader header;
  const auto chunk = hil::read_csv(dir.path() / "telemetry.csv",
                                   {{"t_s", "p_meas_mpa", "wake_latency_us", "loop_flags", "gap_true_deg"}, {}, "t_s"}, &header);
  ASSERT_EQ(chunk.rows(), 5000u);
  EXPECT_DOUBLE_EQ(chunk.values[1][4999], 1.004999);
  EXPECT_DOUBLE_EQ(chunk.values[2][0], 3.25);
  EXPECT_DOUBLE_EQ(chunk.values[3][0], kFlagOverrun);
  EXPECT_EQ(header.names.size(), hil::telemetry::kLoopColumns);

  std::ifstream events(dir.path() / "events.jsonl");
  std::vector<nlohmann::json> lines;
  for (std::string line; std::getline(events, line);) lines.push_back(nlohmann::json::parse(line));
  ASSERT_EQ(lines.size(), 3u);
  for (const auto& j : lines) {
    EXPECT_TRUE(j.contains("utc"));
    EXPECT_TRUE(j.contains("kind"));
  }
  EXPECT_EQ(lines[0]["kind"], "gap_change");
  EXPECT_NEAR(lines[0]["gap_deg"].get<double>(), 0.04 * 180 / M_PI, 1e-9);
  EXPECT_EQ(lines[1]["kind"], "trip");
  EXPECT_EQ(lines[1]["reason"], "watchdog");
  EXPECT_EQ(lines[2]["kind"], "run_start");
}

TEST(Recorder, FlushesWhileRunning) {
  hil::test::TempDir dir;
  Recorder rec(dir.path(), {}, 1024, {}, 20ms);
  for (int i = 0; i < 100; ++i) {
    TelemetryRecord r;
    r.step.t_s = i * 1e-3;
    ASSERT_TRUE(rec.telemetry().try_push(r));
  }
  // Without finish(): the periodic flush alone puts the rows on disk.
  for (int tries = 0; tries < 200 && rec.rows_written() < 100; ++tries) std::this_thread::sleep_for(5ms);
  std::this_thread::sleep_for(60ms);
  const auto chunk = hil::read_csv(dir.path() / "telemetry.csv", {{"t_s"}, {}, "t_s"});
  EXPECT_EQ(chunk.rows(), 100u);
  rec.finish();
}

TEST(Recorder, HardwareRigFilesLeaveTheTruthOut) {
  hil::test::TempDir dir;
  Recorder rec(dir.path(), {}, 64, {}, 10ms, /*with_truth=*/false);
  TelemetryRecord r;
  r.step.p_meas_pa = 1e6;
  r.step.theta_valve_rad = kNaN;  // a hardware rig has none
  r.step.p_chamber_pa = kNaN;
  r.step.gap_true_rad = kNaN;
  ASSERT_TRUE(rec.telemetry().try_push(r));
  EXPECT_EQ(rec.finish(), "");
  hil::CsvHeader header;
  const auto chunk =
      hil::read_csv(dir.path() / "telemetry.csv", {{"t_s", "theta_cmd_deg", "p_meas_mpa", "loop_flags"}, {}, "t_s"}, &header);
  EXPECT_EQ(chunk.rows(), 1u);
  EXPECT_EQ(header.names.size(), hil::telemetry::kLoopColumns - 3);
  for (const char* truth : {"theta_valve_deg", "gap_true_deg", "p_chamber_mpa"}) {
    EXPECT_EQ(std::find(header.names.begin(), header.names.end(), truth), header.names.end()) << truth;
  }
}

// run.json's outcome names round-trip, and their order is how a campaign picks its worst run's.
TEST(RunOutcome, NamesRoundTripAndOrderByHowBad) {
  for (const Outcome o :
       {Outcome::completed, Outcome::stopped, Outcome::aborted, Outcome::error, Outcome::interrupted, Outcome::running})
    EXPECT_EQ(outcome_from(to_string(o)), o) << to_string(o);
  EXPECT_EQ(to_string(Outcome::aborted), "aborted");
  EXPECT_EQ(outcome_from("exploded"), Outcome::error);  // a name it does not know is not "completed"
  EXPECT_LT(Outcome::completed, Outcome::stopped);
  EXPECT_LT(Outcome::stopped, Outcome::aborted);
  EXPECT_LT(Outcome::aborted, Outcome::error);
}
