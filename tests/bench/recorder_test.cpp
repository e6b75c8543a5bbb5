// The recorder writes every row the loop produced, parseable by the strict reader, and the
// events as one JSON object a line.
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>

#include "hil/bench/rt/recorder.hpp"
#include "hil/bench/server/runner.hpp"
#include "hil/csv_reader.hpp"
#include "loop_fixture.hpp"
#include "small_disk.hpp"

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

namespace {

RunRecord ended_record() {
  RunRecord r;
  r.version = "0.1.0";
  r.host = "bench-1";
  r.pid = 4242;
  r.campaign = "paper_adaptive";
  r.run = "adaptive";
  r.run_index = 1;
  r.runs_in_campaign = 3;
  r.rig_name = "sim";
  r.rig_kind = "sim";
  r.start_utc = "2026-11-26T05:00:00.000Z";
  r.stop_utc = "2026-11-26T05:00:18.000Z";
  r.outcome = Outcome::aborted;
  r.reason = "overpressure: 2.61 MPa > 2.5 MPa";
  r.period_s = 1e-3;
  r.duration_s = 18;
  r.speed = 2;
  r.config = {"configs/campaigns/paper_adaptive.yaml",
              "/x/paper_adaptive.yaml",
              "name: paper_adaptive\n",
              "/x/sim.yaml",
              "kind: sim\n",
              "/x/nominal.yaml",
              "effects: []\n"};
  r.ended = true;
  r.trip = RunRecord::Trip{"overpressure", 12.5, 2.61e6, 2.5e6, {}, {}};
  r.rig_health = {{"connected", true}};
  r.periods_run = 12700;
  r.loop = {{"overruns", 0}};
  RunRecord::Telemetry t;
  t.rows_written = 12700;
  t.rows_lost = 0;
  t.rows_unwritten = 0;
  t.events_lost = 0;
  t.events_unwritten = 0;
  t.ring_rows = 65536;
  t.write_error_known = true;
  r.telemetry = t;
  return r;
}

// The same run's record while it goes: none of the end's keys.
RunRecord running_record() {
  RunRecord r = ended_record();
  r.ended = false;
  r.trip.reset();
  r.periods_run.reset();
  r.loop = nullptr;
  r.telemetry.reset();
  r.stop_utc.reset();
  r.reason.reset();
  r.outcome = Outcome::running;
  return r;
}

}  // namespace

// run.json is written and read through one struct: what goes out comes back, key for key.
TEST(RunRecord, RoundTripsThroughRunJson) {
  const hil::test::TempDir dir;
  const RunRecord a = ended_record();
  write_run_record(dir.path(), a);
  const RunRecord b = read_run_record(dir.path());
  EXPECT_EQ(b.to_json(), a.to_json());
  EXPECT_EQ(b.outcome, Outcome::aborted);
  ASSERT_TRUE(b.trip.has_value());
  EXPECT_EQ(b.trip->limit, 2.5e6);
  const nlohmann::json j = a.to_json();
  EXPECT_TRUE(j["telemetry"]["write_error"].is_null());  // the end found none: said, as null
  EXPECT_EQ(j["rig"]["kind"], "sim");
  EXPECT_FALSE(std::filesystem::exists(dir.path() / ".run.json.tmp"));
}

// A record of a run that is still going has none of the end's keys; a count nobody knows (a run
// found interrupted) is left out rather than written as 0.
TEST(RunRecord, WritesOnlyWhatIsKnown) {
  RunRecord r = running_record();
  nlohmann::json j = r.to_json();
  for (const char* key : {"trip", "rig_health", "periods_run", "loop", "telemetry", "interrupted"})
    EXPECT_FALSE(j.contains(key)) << key;
  EXPECT_TRUE(j["stop_utc"].is_null());
  EXPECT_TRUE(j["reason"].is_null());
  RunRecord::Telemetry found;
  found.rows_written = 812;
  found.rows_expected = 18000;
  r.telemetry = found;
  j = r.to_json();
  EXPECT_EQ(j["telemetry"], (nlohmann::json{{"file", "telemetry.csv"}, {"rows_written", 812}, {"rows_expected", 18000}}));
}

// A run.json that is not a run record is refused with the file and the key, never half-read.
TEST(RunRecord, HostileFilesNameTheFileAndTheKey) {
  const hil::test::TempDir dir;
  auto refused = [&](const std::string& text) -> std::string {
    std::ofstream(dir.path() / "run.json") << text;
    try {
      read_run_record(dir.path());
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "(accepted)";
  };
  nlohmann::json good = ended_record().to_json();
  // Cut short (a crash mid-write of a file that is not written whole): where it ends.
  const std::string cut = refused("{\n  \"campaign\": \"x\",\n  \"run\": ");
  EXPECT_NE(cut.find("run.json:3:10: not JSON: "), std::string::npos) << cut;
  EXPECT_NE(cut.find("unexpected end of input"), std::string::npos) << cut;
  EXPECT_NE(refused("[1, 2]").find("not a run record"), std::string::npos);
  nlohmann::json bad = good;
  bad["period_s"] = "fast";
  EXPECT_NE(refused(bad.dump()).find("'period_s' must be a number"), std::string::npos);
  bad = good;
  bad["telemetry"]["rows_lost"] = -3;
  EXPECT_NE(refused(bad.dump()).find("'rows_lost' must be a count"), std::string::npos);
  bad = good;
  bad.erase("config");
  const std::string msg = refused(bad.dump());
  EXPECT_NE(msg.find("'config' is missing"), std::string::npos) << msg;
  EXPECT_NE(msg.find("run.json"), std::string::npos) << msg;
  EXPECT_EQ(refused(good.dump()), "(accepted)");
}

namespace {

// A run folder as a server leaves it when it dies mid-run: run.json says running, the 1 MiB
// reserve is still there, the lock is not held.
std::filesystem::path crashed_run(const std::filesystem::path& runs, const std::string& name) {
  const auto dir = runs / name;
  std::filesystem::create_directories(dir);
  write_run_record(dir, running_record());
  std::ofstream(dir / ".reserve", std::ios::binary) << std::string(1 << 20, '\0');
  std::ofstream(dir / "telemetry.csv") << "t_s,p_meas_mpa\n0,1.2\n0.001,1.2\n0.002,1.2\n";
  return dir;
}

}  // namespace

// On a full disk the restarting server could not append the "interrupted" event and left the run
// `running` for good (listed as running while the server was idle, its review refused, the reserve
// kept): the reserve it frees first is the room that line and the record need.
TEST(InterruptedRuns, ACrashedRunIsMarkedOnAFullDisk) {
  const hil::test::TempDir base;
  const hil::test::SmallDisk disk(base.path() / "runs", "4m");
  if (!disk.mounted()) GTEST_SKIP() << "cannot mount a tmpfs here (not root?)";
  const auto dir = crashed_run(base.path() / "runs", "20261129T080000Z_paper_adaptive_adaptive");
  // events.jsonl fills its last page exactly: one more line needs a page the disk does not have.
  std::string events;
  while (events.size() < 4096 - 64) events += "{\"kind\":\"gap_change\",\"gap_deg\":1.5,\"source\":\"operator\"}\n";
  events += std::string(4096 - events.size() - 1, ' ') + "\n";
  std::ofstream(dir / "events.jsonl") << events;
  disk.fill();

  const auto marked = mark_interrupted_runs(base.path() / "runs");
  ASSERT_EQ(marked.size(), 1u);
  const RunRecord r = read_run_record(dir);
  EXPECT_EQ(r.outcome, Outcome::interrupted);
  ASSERT_TRUE(r.telemetry.has_value());
  EXPECT_EQ(r.telemetry->rows_written, 3u);
  EXPECT_FALSE(std::filesystem::exists(dir / ".reserve"));
  std::ifstream in(dir / "events.jsonl");
  std::string line, last;
  while (std::getline(in, line)) last = line;
  EXPECT_NE(last.find("\"interrupted\""), std::string::npos) << last;
}

// A server killed between writing run.json's replacement and renaming it left the record in a
// temporary: a run with no run.json at all (killed before its first rename) was listed nowhere and
// kept its 1 MiB reserve; one whose final record was not yet renamed was called interrupted
// although its server had written how it ended.
TEST(InterruptedRuns, ARecordLeftInItsTemporaryIsTheRunsRecord) {
  const hil::test::TempDir runs;
  const auto first = crashed_run(runs.path(), "20261129T080000Z_paper_adaptive_none");
  std::filesystem::rename(first / "run.json", first / ".run.json.tmp4242-1");
  const auto ended = crashed_run(runs.path(), "20261129T080100Z_paper_adaptive_adaptive");
  const hil::test::TempDir scratch;
  write_run_record(scratch.path(), ended_record());  // the final record, as its server wrote it
  std::filesystem::rename(scratch.path() / "run.json", ended / ".run.json.tmp4242-4");
  const auto nothing = runs.path() / "20261129T080200Z_paper_adaptive_adaptive_paper";  // died before any record
  std::filesystem::create_directories(nothing);
  std::ofstream(nothing / ".reserve") << "x";

  const auto marked = mark_interrupted_runs(runs.path());
  ASSERT_EQ(marked.size(), 1u);
  EXPECT_EQ(marked[0], first);
  EXPECT_EQ(read_run_record(first).outcome, Outcome::interrupted);
  const RunRecord end = read_run_record(ended);
  EXPECT_EQ(end.outcome, Outcome::aborted);
  EXPECT_EQ(end.reason, "overpressure: 2.61 MPa > 2.5 MPa");
  for (const auto& dir : {first, ended, nothing}) {
    EXPECT_FALSE(std::filesystem::exists(dir / ".reserve")) << dir;
    for (const auto& f : std::filesystem::directory_iterator(dir))
      EXPECT_FALSE(f.path().filename().string().starts_with(".run.json.tmp")) << f.path();
  }
}

// Issue 38 (the scan a server makes at its start): a run folder is hostile input. A folder that is a
// symbolic link to one outside the runs folder, or a run's telemetry.csv and events.jsonl linked to
// files elsewhere, were followed: the scan trimmed, counted and appended to the files outside
// (the server runs as root). A run.json nested 20 000 deep was parsed unbounded. Now none of these
// is followed or parsed; the run whose files are links is still marked, from what is its own.
TEST(InterruptedRuns, NoLinkIsFollowedAndNoRunJsonParsedUnbounded) {
  const hil::test::TempDir runs, outside;
  // A folder outside, shaped like a crashed run, reached through a link in the runs folder.
  const auto elsewhere = crashed_run(outside.path(), "elsewhere");
  std::filesystem::create_directory_symlink(elsewhere, runs.path() / "20261129T080000Z_linked_folder");
  // A crashed run whose telemetry and events are links to files outside, each with a cut last line.
  const std::string victim_text = "root:x:0:0:root:/root:/bin/bash\nno newline at the end";
  for (const char* name : {"victim.csv", "victim.jsonl"}) std::ofstream(outside.path() / name) << victim_text;
  const auto linked_files = crashed_run(runs.path(), "20261129T080100Z_linked_files");
  std::filesystem::remove(linked_files / "telemetry.csv");
  std::filesystem::create_symlink(outside.path() / "victim.csv", linked_files / "telemetry.csv");
  std::filesystem::create_symlink(outside.path() / "victim.jsonl", linked_files / "events.jsonl");
  // A run.json nested 20 000 deep.
  const auto deep = runs.path() / "20261129T080200Z_deep";
  std::filesystem::create_directories(deep);
  std::ofstream(deep / "run.json") << std::string(20000, '[') << std::string(20000, ']');

  const auto marked = mark_interrupted_runs(runs.path());
  ASSERT_EQ(marked.size(), 1u);
  EXPECT_EQ(marked[0], linked_files);
  // Nothing outside changed: the linked folder's record still says running, its reserve is kept,
  // and the victims keep their cut last line and get no appended event.
  EXPECT_EQ(read_run_record(elsewhere).outcome, Outcome::running);
  EXPECT_TRUE(std::filesystem::exists(elsewhere / ".reserve"));
  for (const char* name : {"victim.csv", "victim.jsonl"}) {
    std::ifstream in(outside.path() / name);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(text, victim_text) << name;
  }
  // The run with linked files: marked from its own run.json, no rows counted from the link.
  const RunRecord r = read_run_record(linked_files);
  EXPECT_EQ(r.outcome, Outcome::interrupted);
  ASSERT_TRUE(r.telemetry.has_value());
  EXPECT_EQ(r.telemetry->rows_written, 0u);
  // The deep run.json is left as it is (unreadable), and not parsed.
  EXPECT_TRUE(std::filesystem::exists(deep / "run.json"));
}
