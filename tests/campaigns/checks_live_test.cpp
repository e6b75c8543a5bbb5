// A campaign's checks while the run goes on (RunChecks::live): what is decided, when, and that a
// decided verdict is the one the run's end gives, against hand-made records whose answers are
// closed forms.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <map>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/campaign/checks.hpp"
#include "hil/bench/rt/rt_loop.hpp"
#include "hil/bench/rt/telemetry_record.hpp"
#include "hil/config.hpp"
#include "hil/units.hpp"
#include "checks_fixtures.hpp"

namespace {

using hil::bench::Campaign;
using hil::bench::LiveCheck;
using hil::bench::LiveVerdict;
using hil::bench::RunChecks;
using hil::bench::TelemetryRecord;
using hil::bench::Verdict;

using hil::test::campaign_with;
using hil::test::record;

std::map<std::string, LiveCheck> by_name(const std::vector<LiveCheck>& v) {
  std::map<std::string, LiveCheck> m;
  for (const auto& c : v) m[c.result.check] = c;
  return m;
}

// Feeds `rows` records made by `make` (k -> record), and after each the live verdicts: `seen`
// gets the first row index at which each check showed each live verdict.
using Seen = std::map<std::string, std::map<LiveVerdict, long>>;
Seen feed(RunChecks& checks, long rows, const std::function<TelemetryRecord(long)>& make) {
  Seen seen;
  for (long k = 0; k < rows; ++k) {
    checks.add(make(k));
    RunChecks::Progress copy;  // what the served run hands to the status: a copy
    copy = checks.progress();
    for (const auto& c : checks.live(copy)) seen[c.result.check].emplace(c.verdict, k);
  }
  return seen;
}

// Before any row every check is pending; a metric stays pending until the end, whatever happens.
TEST(LiveChecks, PendingFromTheStartMetricsUntilTheEnd) {
  const Campaign c = campaign_with(
      "- {name: iae, metric: iae_mpa_s, max: 1}\n"
      "- {name: safe, signal: safe_state, max: 0}\n");
  RunChecks checks(c, "run");
  const auto before = by_name(checks.live(checks.progress()));
  ASSERT_EQ(before.size(), 2u);
  for (const auto& [name, live] : before) {
    EXPECT_EQ(live.verdict, LiveVerdict::pending) << name;
    EXPECT_FALSE(live.decided) << name;
  }
  EXPECT_TRUE(before.at("iae").at_end);
  EXPECT_EQ(before.at("iae").result.max, 1.0);
  EXPECT_EQ(before.at("iae").to_json().at("verdict"), "pending");
  EXPECT_NE(before.at("iae").result.message.find("judged at its end"), std::string::npos);
  const Seen seen = feed(checks, 3000, [](long k) { return record(k * 1e-3, 1, 1); });
  EXPECT_EQ(seen.at("iae").size(), 1u);   // pending only
  EXPECT_EQ(seen.at("safe").size(), 1u);  // the whole run is its window: pending until the end
  EXPECT_EQ(seen.at("safe").begin()->first, LiveVerdict::pending);
}

// A step of the reference from 1.0 to 1.5 MPa at 1 s, the pressure following it first-order with
// tau = 0.5 s; the safe state entered at 2.2 s.
//  - safe (no safe state, the whole run): pending, FAIL decided at the row of 2.2 s;
//  - first_second (|error| <= 0.1 MPa over [0, 1) after the start): the window closes at 1 s and
//    no start comes again: pass decided there;
//  - steps (error within 5 % over [1.5, 1.75) after each step): 0.5 exp(-1) / 1.5 = 0.123 at the
//    window's first row, 1.5 s: FAIL decided there;
//  - steps_loose (the same within 20 %): pending while the window is open, "passing" (pass so
//    far: another step may come) from 1.75 s; the end says pass.
TEST(LiveChecks, DecidedAsSoonAsTheRecordsAllowAndAsTheEndSays) {
  const Campaign c = campaign_with(
      "- {name: safe, signal: safe_state, max: 0}\n"
      "- {name: first_second, signal: pressure_error_mpa, for_s: 1, max: 0.1}\n"
      "- {name: steps, signal: pressure_error_rel, after: reference_change, delay_s: 0.5, for_s: 0.25, max: 0.05}\n"
      "- {name: steps_loose, signal: pressure_error_rel, after: reference_change, delay_s: 0.5, for_s: 0.25, max: 0.2}\n");
  RunChecks checks(c, "run");
  const double tau_s = 0.5;
  const Seen seen = feed(checks, 3000, [&](long k) {
    const double t = k * 1e-3;
    TelemetryRecord r = record(t, t < 1 ? 1.0 : 1.5, t < 1 ? 1.0 : 1.5 - 0.5 * std::exp(-(t - 1) / tau_s));
    if (k >= 2200) r.flags |= hil::bench::kFlagSafeState;
    return r;
  });
  EXPECT_EQ(seen.at("safe").at(LiveVerdict::pending), 0);
  EXPECT_EQ(seen.at("safe").at(LiveVerdict::fail), 2200);
  EXPECT_EQ(seen.at("first_second").at(LiveVerdict::pending), 0);
  EXPECT_EQ(seen.at("first_second").at(LiveVerdict::pass), 1000);
  EXPECT_EQ(seen.at("steps").at(LiveVerdict::fail), 1500);
  EXPECT_EQ(seen.at("steps").count(LiveVerdict::passing), 0u);
  EXPECT_EQ(seen.at("steps_loose").at(LiveVerdict::passing), 1750);
  EXPECT_EQ(seen.at("steps_loose").count(LiveVerdict::pass), 0u);  // never decided: a step may come

  // At the end: the live verdicts' values are the final ones, and each decided one is the final verdict.
  const auto final_results = checks.finish({}, 0, {});
  const auto live = by_name(checks.live(checks.progress()));
  for (const auto& f : final_results) {
    const LiveCheck& l = live.at(f.check);
    EXPECT_EQ(l.result.value, f.value) << f.check;
    EXPECT_EQ(l.result.samples, f.samples) << f.check;
    if (l.decided) {
      EXPECT_STREQ(to_string(l.verdict), to_string(f.verdict)) << f.check;
    }
  }
  EXPECT_TRUE(live.at("safe").decided);
  EXPECT_NEAR(live.at("steps").result.value, 0.5 * std::exp(-1.0) / 1.5, 1e-9);
  EXPECT_EQ(live.at("steps_loose").verdict, LiveVerdict::passing);
  for (const auto& f : final_results)
    EXPECT_EQ(f.verdict, f.check == "safe" || f.check == "steps" ? Verdict::fail : Verdict::pass) << f.check;
}

// The gap estimate from the 2nd reversal after the start and after each gap change (reversals at
// 1, 2, 3, 4 s, the gap 1 -> 2 deg at 2.5 s; checks_test.cpp's case): the first window [2, 2.5)
// closes at the change with 0.05 deg off, so both checks are "passing" from 2.5 s; the second
// opens at 4 s with 0.2 deg off: the 0.1 deg check FAILs there, the 12 % one (0.1 of the gap)
// stays passing. With every reversal passed and the window open to the end, nothing more decides.
TEST(LiveChecks, AWindowsVerdictWhenItCloses) {
  const Campaign c = campaign_with(
      "- {name: tracks, signal: gap_error_rel, after: [start, gap_change], from_reversal: 2, max: 0.12}\n"
      "- {name: tracks_deg, signal: gap_error_deg, after: [start, gap_change], from_reversal: 2, max: 0.1}\n",
      {1, 2, 3, 4});
  RunChecks checks(c, "run");
  const Seen seen = feed(checks, 5000, [](long k) {
    const double t = k * 1e-3;
    return record(t, 1, 1, t < 2.5 ? 1.0 : 2.0, t < 1.2 ? 0.0 : t < 3.4 ? 1.05 : 1.8);
  });
  for (const char* name : {"tracks", "tracks_deg"}) {
    EXPECT_EQ(seen.at(name).at(LiveVerdict::pending), 0) << name;
    EXPECT_EQ(seen.at(name).at(LiveVerdict::passing), 2500) << name;
  }
  EXPECT_EQ(seen.at("tracks_deg").at(LiveVerdict::fail), 4000);
  EXPECT_EQ(seen.at("tracks").count(LiveVerdict::fail), 0u);
  const auto final_results = checks.finish({}, 0, {});
  EXPECT_EQ(final_results[0].verdict, Verdict::pass);
  EXPECT_EQ(final_results[1].verdict, Verdict::fail);
}

}  // namespace
