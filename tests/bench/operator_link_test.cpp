// The console's trust parts without a server (issue 40): the operator link's rule (operator_link.hpp)
// on made-up times, the stream's state for a runner status (status_stream.hpp), the event feed by
// offset (event_feed.hpp) on a written events.jsonl, and the rig file's require_operator keys with
// their located errors; what a restarted server's status says of the last run (issue 52). The same
// parts run in the real server in tests/console/console_link_test.mjs and console_after_fault_test.mjs.
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>

#include <nlohmann/json.hpp>

#include "hil/bench/rt/rig_config.hpp"
#include "hil/bench/server/runner.hpp"
#include "server/event_feed.hpp"
#include "server/request_guard.hpp"
#include "server/operator_link.hpp"
#include "server/status_stream.hpp"
#include "temp_file.hpp"

using nlohmann::json;
using namespace std::chrono_literals;
using hil::bench::OperatorLink;

namespace {

json running(const std::string& dir, bool required, double timeout_s) {
  return {{"state", "running"}, {"run_dir", dir}, {"operator_link", {{"required", required}, {"timeout_s", timeout_s}}}};
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST(OperatorLink, LostOnlyWhenRequiredAndSilentForTheTimeoutCountedFromTheRunsStart) {
  OperatorLink link;
  const auto t0 = OperatorLink::Clock::now();
  link.heard();
  // Not required: never lost, however long the silence.
  EXPECT_FALSE(link.lost(running("a", false, 1.0), t0 + 1h));
  // Required: the timeout counts from the run's first sight, not from a word heard long before.
  EXPECT_FALSE(link.lost(running("b", true, 2.0), t0 + 1h));
  EXPECT_FALSE(link.lost(running("b", true, 2.0), t0 + 1h + 1900ms));
  const auto why = link.lost(running("b", true, 2.0), t0 + 1h + 2100ms);
  ASSERT_TRUE(why);
  EXPECT_EQ(why->rfind("operator link lost: no console or ctl client heard for 2.1 s", 0), 0u) << *why;
  // Said once for a run; a new run starts its own count.
  EXPECT_FALSE(link.lost(running("b", true, 2.0), t0 + 1h + 5s));
  EXPECT_FALSE(link.lost(running("c", true, 2.0), t0 + 1h + 5s));
  EXPECT_TRUE(link.lost(running("c", true, 2.0), t0 + 1h + 7100ms));
  // Only a running loop goes to the safe state: not one still setting up, already safe, or idle.
  json starting = running("d", true, 1.0);
  starting["state"] = "starting";
  EXPECT_FALSE(link.lost(starting, t0 + 2h));
  EXPECT_FALSE(link.lost(starting, t0 + 3h));
  EXPECT_FALSE(link.lost(json{{"state", "idle"}}, t0 + 4h));
}

TEST(OperatorLink, AClientHeardKeepsTheLink) {
  OperatorLink link;
  const auto t0 = OperatorLink::Clock::now();
  EXPECT_FALSE(link.lost(running("a", true, 0.5), t0));
  link.heard();  // now, after t0: silence is counted from here
  EXPECT_GE(link.silent_s(OperatorLink::Clock::now()), 0.0);
  EXPECT_LT(link.silent_s(OperatorLink::Clock::now()), 60.0);
  EXPECT_FALSE(link.lost(running("a", true, 0.5), OperatorLink::Clock::now() + 100ms));
}

TEST(StatusStream, SafeIsACommandedSafeStateTrippedAnInterlockEachWithItsReason) {
  json s = {{"state", "safe"},
            {"campaign", "c"},
            {"run", "r"},
            {"runs", {"r", "q"}},
            {"run_dir", "D"},
            {"safety", {{"safe_state", true}, {"trip", "operator abort"}, {"reason", "operator abort: test"}}},
            {"progress", {{"t_s", 1.5}, {"duration_s", 18.0}, {"fraction", 0.1}}}};
  json m = hil::bench::status_message(s, 7, 0.25);
  EXPECT_EQ(m["type"], "status");
  EXPECT_EQ(m["seq"], 7);
  EXPECT_EQ(m["state"], "safe");
  EXPECT_EQ(m["reason"], "operator abort: test");
  EXPECT_EQ(m["runs"], json({"r", "q"}));
  EXPECT_EQ(m["run_t_s"], 1.5);
  EXPECT_EQ(m["silent_s"], 0.25);
  s["safety"] = {{"safe_state", true}, {"trip", "overpressure"}};
  m = hil::bench::status_message(s, 8, 1e9);
  EXPECT_EQ(m["state"], "tripped");
  EXPECT_EQ(m["reason"], "interlock: overpressure");
  EXPECT_EQ(m["silent_s"], -1);  // never heard
  m = hil::bench::status_message({{"state", "idle"}, {"last", {{"campaign", "c"}, {"outcome", "aborted"}, {"reason", "x"}}}}, 9,
                                 0);
  EXPECT_EQ(m["state"], "idle");
  EXPECT_TRUE(m["reason"].is_null());
  EXPECT_EQ(m["last"]["outcome"], "aborted");
}

// The status carries the last run's end whatever the state, and which campaign of its name runs.
TEST(StatusStream, CarriesTheLastRunAndTheCampaignsStart) {
  const json last_run = {{"dir", "d"}, {"run", "none"}, {"outcome", "interrupted"}, {"reason", "why"}};
  json m = hil::bench::status_message({{"state", "idle"}, {"last_run", last_run}}, 1, 0);
  EXPECT_EQ(m["last_run"], last_run);
  m = hil::bench::status_message(
      {{"state", "running"}, {"campaign_started_utc", "2026-12-08T03:00:00.000Z"}, {"last_run", last_run}}, 2, 0);
  EXPECT_EQ(m["campaign_started_utc"], "2026-12-08T03:00:00.000Z");
  EXPECT_EQ(m["last_run"]["outcome"], "interrupted");
}

namespace {
// A run folder with a run.json of `outcome` (no lock held: its server is gone).
std::filesystem::path run_folder(const std::filesystem::path& runs, const std::string& name, hil::bench::Outcome outcome) {
  hil::bench::RunRecord r;
  r.campaign = "paper_adaptive";
  r.run = name.substr(name.rfind('_') + 1);
  r.start_utc = "2026-12-08T03:00:00.000Z";
  r.pid = 4242;
  r.period_s = 1e-3;
  r.duration_s = 18;
  r.outcome = outcome;
  if (outcome != hil::bench::Outcome::running) r.stop_utc = "2026-12-08T03:00:18.000Z", r.reason = "operator abort: x";
  r.ended = outcome != hil::bench::Outcome::running;  // the end keys, "trip" among them, are written
  if (outcome == hil::bench::Outcome::aborted) r.trip = hil::bench::RunRecord::Trip{"operator abort", 4.0, {}, {}, {}, {}};
  const auto dir = runs / name;
  std::filesystem::create_directories(dir);
  hil::bench::write_run_record(dir, r);
  return dir;
}
}  // namespace

// At a server's start the newest ended run is the status's last_run: a run its dead server left
// "running" once marked interrupted (with the restarted server's reason), else the newest one that
// ended; a folder that is a symbolic link, holds no run.json or an unreadable one is passed over.
TEST(LastRun, TheNewestEndedRunOfTheRunsFolderAfterTheInterruptedScan) {
  using hil::bench::Outcome;
  const hil::test::TempDir runs;
  EXPECT_FALSE(hil::bench::newest_ended_run(runs.path()).has_value());
  run_folder(runs.path(), "20261208T030000Z_paper_adaptive_adaptive", Outcome::aborted);
  std::filesystem::create_directories(runs.path() / "20261208T040000Z_paper_adaptive_empty");
  const auto bad = runs.path() / "20261208T050000Z_paper_adaptive_bad";
  std::filesystem::create_directories(bad);
  std::ofstream(bad / "run.json") << "{not json";
  std::filesystem::create_directory_symlink(runs.path() / "20261208T030000Z_paper_adaptive_adaptive",
                                            runs.path() / "20261208T060000Z_paper_adaptive_link");
  auto last = hil::bench::newest_ended_run(runs.path());
  ASSERT_TRUE(last.has_value());
  EXPECT_EQ(last->dir, "20261208T030000Z_paper_adaptive_adaptive");
  EXPECT_EQ(last->outcome, Outcome::aborted);
  EXPECT_EQ(last->to_json()["trip"], "operator abort");
  EXPECT_EQ(last->to_json()["outcome"], "aborted");

  run_folder(runs.path(), "20261208T070000Z_paper_adaptive_none", Outcome::running);  // its server was killed
  EXPECT_EQ(hil::bench::newest_ended_run(runs.path())->dir,
            "20261208T030000Z_paper_adaptive_adaptive");  // a run under way is no end
  ASSERT_EQ(hil::bench::mark_interrupted_runs(runs.path()).size(), 1u);
  last = hil::bench::newest_ended_run(runs.path());
  ASSERT_TRUE(last.has_value());
  EXPECT_EQ(last->dir, "20261208T070000Z_paper_adaptive_none");
  EXPECT_EQ(last->run, "none");
  EXPECT_EQ(last->outcome, Outcome::interrupted);
  ASSERT_TRUE(last->reason.has_value());
  EXPECT_NE(last->reason->find("pid 4242"), std::string::npos) << *last->reason;
  EXPECT_FALSE(last->stop_utc.empty());
  EXPECT_TRUE(last->to_json()["trip"].is_null());
}

namespace {

// The feed of DIR/events.jsonl, opened as the route opens it.
json feed(const std::filesystem::path& dir, std::uint64_t offset, std::uint64_t max_bytes = hil::bench::kEventFeedMaxBytes) {
  const auto f = hil::bench::open_inside(dir, {"events.jsonl"});
  const json r = hil::bench::event_feed(f.fd, f.size, "events.jsonl", offset, max_bytes);
  ::close(f.fd);
  return r;
}

}  // namespace

TEST(EventFeed, OperatorEventsWholeOverrunsPerSecondAndOnlyWholeLinesFromAnOffset) {
  hil::test::TempDir dir;
  std::string text;
  for (int i = 0; i < 2500; ++i) {
    text += json{{"utc", "u"}, {"t_s", 3 + i * 0.001}, {"kind", "overrun"}, {"source", "loop"}, {"late_us", 5 + i % 50}}.dump() +
            "\n";
    if (i % 500 == 0) text += json{{"utc", "u"}, {"t_s", 3 + i * 0.001}, {"kind", "gap_change"}, {"gap_deg", i}}.dump() + "\n";
  }
  dir.write("events.jsonl", text + "{\"kind\": \"half a li");  // a line being written
  std::uint64_t offset = 0;
  int gap_changes = 0, overruns = 0, looks = 0;
  json worst = json::object();
  for (;; ++looks) {
    const json r = feed(dir.path(), offset, 16 * 1024);
    for (const auto& e : r["events"]) {
      gap_changes += e["kind"] == "gap_change";
      // The label the console marks it with, the reports' wording (run_marks.hpp).
      EXPECT_EQ(e.value("mark", ""), "gap " + std::to_string(e["gap_deg"].get<int>()) + " deg");
    }
    for (const auto& s : r["summaries"]) {
      EXPECT_EQ(s["kind"], "overrun");
      overruns += s["count"].get<int>();
      const std::string second = std::to_string(s["t0_s"].get<int>());
      worst[second] = std::max(worst.value(second, 0.0), s["worst_late_us"].get<double>());
    }
    ASSERT_GT(r["next_offset"].get<std::uint64_t>(), offset);
    offset = r["next_offset"];
    if (offset == text.size()) break;  // the half line is left for a later look
  }
  EXPECT_EQ(gap_changes, 5);
  EXPECT_EQ(overruns, 2500);
  EXPECT_EQ(worst, json({{"3", 54.0}, {"4", 54.0}, {"5", 54.0}}));
  EXPECT_GT(looks, 5);
  // An offset inside a line, or past the end: a 400's field, never a torn line.
  const std::string inside = error_of([&] { feed(dir.path(), 3); });
  EXPECT_NE(inside.find("'offset' 3 is not the start of a line"), std::string::npos) << inside;
  EXPECT_NE(error_of([&] { feed(dir.path(), 1u << 30); }).find("past the end"), std::string::npos);
}

// A line longer than one answer covers (a 300 KiB line gave a next_offset inside itself, which
// the next call refused: the feed stood still) is skipped whole, counted, with a note; the feed
// goes on from the line after it. One still being written (no newline yet) is waited for.
TEST(EventFeed, ALineLongerThanTheLimitIsSkippedWholeAndCounted) {
  hil::test::TempDir dir;
  const std::string before = json{{"utc", "u"}, {"t_s", 1.0}, {"kind", "gap_change"}, {"gap_deg", 1}}.dump() + "\n";
  const std::string huge = "{\"kind\": \"x\", \"pad\": \"" + std::string(300 * 1024, 'a') + "\"}\n";
  const std::string after = json{{"utc", "u"}, {"t_s", 2.0}, {"kind", "gap_change"}, {"gap_deg", 2}}.dump() + "\n";
  dir.write("events.jsonl", before + huge + after);
  json r = feed(dir.path(), 0);
  EXPECT_EQ(r["events"].size(), 1u) << r.dump().substr(0, 300);
  ASSERT_EQ(r["next_offset"], before.size());
  r = feed(dir.path(), before.size());
  EXPECT_EQ(r["next_offset"], before.size() + huge.size()) << r.dump().substr(0, 300);
  EXPECT_EQ(r["too_long"], 1);
  EXPECT_EQ(r["unreadable"], 1);
  EXPECT_NE(r.value("note", "").find("skipped"), std::string::npos) << r.dump().substr(0, 300);
  r = feed(dir.path(), r["next_offset"]);  // accepted: the start of a line
  ASSERT_EQ(r["events"].size(), 1u) << r.dump();
  EXPECT_EQ(r["events"][0]["gap_deg"], 2);
  EXPECT_EQ(r["next_offset"], before.size() + huge.size() + after.size());
  // A long line without its newline yet: nothing skipped, the offset stays for a later look.
  dir.write("events.jsonl", before + huge.substr(0, huge.size() - 1));
  r = feed(dir.path(), before.size());
  EXPECT_EQ(r["next_offset"], before.size());
  EXPECT_FALSE(r.contains("too_long"));
}

TEST(RigFile, RequireOperatorKeysAreCheckedWhereTheyAre) {
  hil::test::TempDir dir;
  const std::string safety =
      "safety: {cmd_min_deg: -5, cmd_max_deg: 35, rate_limit_deg_s: 100, p_max_mpa: 2.5, p_min_mpa: 0.2}\n";
  const auto off = hil::bench::load_rig_config(dir.write("rigs/off.yaml", "kind: sim\n" + safety));
  EXPECT_FALSE(off.require_operator);
  const auto on = hil::bench::load_rig_config(
      dir.write("rigs/on.yaml", "kind: sim\n" + safety + "require_operator: true\noperator_timeout_s: 2.5\n"));
  EXPECT_TRUE(on.require_operator);
  EXPECT_EQ(on.operator_timeout_s, 2.5);
  std::string e = error_of(
      [&] { hil::bench::load_rig_config(dir.write("rigs/short.yaml", "kind: sim\n" + safety + "operator_timeout_s: 0.1\n")); });
  EXPECT_NE(e.find("short.yaml:3:"), std::string::npos) << e;
  EXPECT_NE(e.find("operator_timeout_s"), std::string::npos) << e;
  EXPECT_NE(e.find("0.5..3600"), std::string::npos) << e;
  e = error_of(
      [&] { hil::bench::load_rig_config(dir.write("rigs/yes.yaml", "kind: sim\n" + safety + "require_operator: maybe\n")); });
  EXPECT_NE(e.find("yes.yaml:3:"), std::string::npos) << e;
  EXPECT_NE(e.find("require_operator"), std::string::npos) << e;
}
