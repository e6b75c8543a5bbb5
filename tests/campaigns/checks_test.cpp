// A campaign's checks: the `checks:` block's errors (file:line:key), and the evaluator against
// hand-made records whose answers are closed forms.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <regex>
#include <sstream>
#include <tuple>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/campaign/checks.hpp"
#include "hil/bench/rt/rt_loop.hpp"
#include "hil/bench/rt/telemetry_record.hpp"
#include "hil/config.hpp"
#include "hil/units.hpp"
#include "checks_fixtures.hpp"
#include "support/temp_file.hpp"

namespace {

using hil::bench::Campaign;
using hil::bench::CheckResult;
using hil::bench::RunChecks;
using hil::bench::RunSummary;
using hil::bench::TelemetryRecord;
using hil::bench::Verdict;

// paper_adaptive with its checks block replaced by `checks` (YAML lines), loaded from a temporary
// folder; the error, or "no error".
std::string load_with_checks(const std::string& checks, int* first_line = nullptr) {
  std::ifstream in(hil::test::source_path("configs/campaigns/paper_adaptive.yaml"));
  std::stringstream ss;
  ss << in.rdbuf();
  std::string text = std::regex_replace(ss.str(), std::regex("plant: \\.\\./plant/nominal\\.yaml"),
                                        "plant: " + hil::test::source_path("configs/plant/nominal.yaml").string());
  const auto at = text.find("\nchecks:");
  if (at != std::string::npos) text.resize(at + 1);
  if (first_line != nullptr) *first_line = 2 + static_cast<int>(std::count(text.begin(), text.end(), '\n'));
  text += "checks:\n" + checks;
  hil::test::TempDir dir;
  try {
    (void)hil::bench::load_campaign(dir.write("bad.yaml", text));
    return "no error";
  } catch (const hil::cfg::Error& e) {
    return e.what();
  }
}

void expect_error(const std::string& checks, int line_in_block, const std::string& key, const std::string& words) {
  int first = 0;
  const std::string error = load_with_checks(checks, &first);
  EXPECT_NE(error.find("bad.yaml:" + std::to_string(first + line_in_block) + ":"), std::string::npos) << error;
  EXPECT_NE(error.find(key), std::string::npos) << error;
  EXPECT_NE(error.find(words), std::string::npos) << error;
}

TEST(CheckConfig, ErrorsNameFileLineAndKey) {
  EXPECT_EQ(load_with_checks("  - {name: a, metric: iae_mpa_s, max: 2}\n"), "no error");
  expect_error("  - {name: a, metric: stall_vs_nonee, max: 1}\n", 0, "checks[0].metric", "did you mean 'stall_vs_none'");
  expect_error("  - name: a\n    runs: [adaptive, adaptve]\n    metric: iae_mpa_s\n    max: 1\n", 1, "checks[0].runs[1]",
               "no run 'adaptve' (did you mean 'adaptive'?)");
  expect_error("  - {name: a, metric: iae_mpa_s, signal: safe_state, max: 0}\n", 0, "checks[0]", "either 'metric'");
  expect_error("  - {name: a, metric: iae_mpa_s}\n", 0, "checks[0]", "needs a limit");
  expect_error("  - {name: a, signal: safe_state, reduce: max, max: 0}\n", 0, "checks[0].reduce", "applies to a metric check");
  expect_error("  - {name: a, metric: iae_mpa_s, from_reversal: 2, max: 1}\n", 0, "checks[0].from_reversal", "per reversal only");
  expect_error("  - {name: a, signal: gap_error_rel, after: gap_chnage, max: 0.1}\n", 0, "checks[0].after",
               "did you mean 'gap_change'");
  expect_error("  - {name: a, signal: gap_error_rel, after: [start, revrsal], max: 0.1}\n", 0, "checks[0].after[1]",
               "unknown event 'revrsal'");
  expect_error("  - {name: a, signal: pressure_error_rel, delay_s: -1, max: 0.1}\n", 0, "checks[0].delay_s", "time >= 0");
  expect_error("  - {name: a, metric: gap_error_deg, from_reversal: 3, to_reversal: 2, max: 1}\n", 0, "checks[0].to_reversal",
               ">= from_reversal");
  expect_error("  - {name: a, metric: iae_mpa_s, min: 2, max: 1}\n", 0, "checks[0].max", "below min");
  expect_error("  - {name: a, metric: iae_mpa_s, max: 2}\n  - {name: a, metric: rmse_mpa, max: 2}\n", 1, "checks[1].name",
               "two checks have this name");
  expect_error("  - {name: 'a b', metric: iae_mpa_s, max: 2}\n", 0, "checks[0].name", "plain name");
  expect_error("  - {name: a, metric: iae_mpa_s, maxx: 2}\n", 0, "maxx", "did you mean 'max'");
}

using hil::test::campaign_with;
using hil::test::record;

const CheckResult& find(const std::vector<CheckResult>& results, const std::string& name) {
  for (const auto& r : results)
    if (r.check == name) return r;
  throw std::runtime_error("no result " + name);
}

// A step of the reference from 1.0 to 1.5 MPa at 1 s, the pressure following it first-order with
// tau = 0.5 s: 1.5 s after the step the relative error is 0.5 exp(-3) / 1.5, and from there it
// only falls, so that is the window's worst, at t = 2.5 s.
TEST(RunChecks, PressureWithinAFractionOfTheReferenceAfterEveryStep) {
  const Campaign c = campaign_with(
      "- {name: settles, signal: pressure_error_rel, after: reference_change, delay_s: 1.5, max: 0.05}\n"
      "- {name: settles_tight, signal: pressure_error_rel, after: reference_change, delay_s: 1.5, max: 0.01}\n"
      "- {name: half_second, signal: pressure_error_mpa, after: reference_change, delay_s: 0.5, for_s: 0.25, max: 1}\n");
  RunChecks checks(c, "run");
  const double tau_s = 0.5, dt_s = 1e-3;
  for (long k = 0; k < 5000; ++k) {
    const double t = k * dt_s;
    const double ref = t < 1 ? 1.0 : 1.5;
    const double meas = t < 1 ? 1.0 : 1.5 - 0.5 * std::exp(-(t - 1) / tau_s);
    checks.add(record(t, ref, meas));
  }
  const auto results = checks.finish({}, 0, {});
  ASSERT_EQ(results.size(), 3u);
  const double expected = 0.5 * std::exp(-1.5 / tau_s) / 1.5;
  const auto& settles = find(results, "settles");
  EXPECT_EQ(settles.verdict, Verdict::pass) << settles.message;
  EXPECT_NEAR(settles.value, expected, 1e-9);
  EXPECT_NEAR(settles.at_s, 2.5, 1e-9);
  EXPECT_EQ(settles.samples, 2500);  // 2.5 .. 4.999 s
  const auto& tight = find(results, "settles_tight");
  EXPECT_EQ(tight.verdict, Verdict::fail);
  EXPECT_NE(tight.message.find("0.0166 > max 0.01"), std::string::npos) << tight.message;
  // A window of for_s: 0.5 .. 0.75 s after the step, worst at its start.
  const auto& half = find(results, "half_second");
  EXPECT_NEAR(half.value, 0.5 * std::exp(-0.5 / tau_s), 1e-9);
  EXPECT_EQ(half.samples, 250);
}

// The gap estimate against the truth from the 2nd reversal after the start and after each gap
// change: reversals at 1, 2, 3, 4 s, the gap 1 -> 2 deg at 2.5 s. The windows are [2, 2.5) (two
// reversals since the start, then the change closes it) and [4, 5) (the 2nd after the change):
// the estimate's 0.05 deg off before and 0.2 deg off after are seen, its 0.95 deg off between
// 2.5 and 4 s is not.
TEST(RunChecks, GapEstimateFromTheNthReversalAfterEachGapChange) {
  const Campaign c = campaign_with(
      "- {name: tracks, signal: gap_error_rel, after: [start, gap_change], from_reversal: 2, max: 0.12}\n"
      "- {name: tracks_deg, signal: gap_error_deg, after: [start, gap_change], from_reversal: 2, max: 0.1}\n"
      "- {name: safe, signal: safe_state, max: 0}\n",
      {1, 2, 3, 4});
  RunChecks checks(c, "run");
  for (long k = 0; k < 5000; ++k) {
    const double t = k * 1e-3;
    const double truth = t < 2.5 ? 1.0 : 2.0;
    const double est = t < 1.2 ? 0.0 : t < 3.4 ? 1.05 : 1.8;
    TelemetryRecord r = record(t, 1, 1, truth, est);
    if (k == 4321) r.flags |= hil::bench::kFlagSafeState;
    checks.add(r);
  }
  const auto results = checks.finish({}, 0, {});
  const auto& rel = find(results, "tracks");
  EXPECT_EQ(rel.samples, 1500);
  EXPECT_NEAR(rel.value, 0.1, 1e-9);  // 0.2 deg of 2 deg (0.05 of 1 deg before)
  EXPECT_NEAR(rel.at_s, 4.0, 1e-9);
  EXPECT_EQ(rel.verdict, Verdict::pass);
  const auto& deg = find(results, "tracks_deg");
  EXPECT_NEAR(deg.value, 0.2, 1e-9);
  EXPECT_EQ(deg.verdict, Verdict::fail);
  const auto& safe = find(results, "safe");
  EXPECT_EQ(safe.verdict, Verdict::fail);
  EXPECT_EQ(safe.value, 1);
  EXPECT_NEAR(safe.at_s, 4.321, 1e-9);
}

RunSummary summary_with(std::vector<double> stall_s, std::vector<std::pair<double, double>> gap_est_true = {}) {
  RunSummary s;
  for (std::size_t i = 0; i < stall_s.size(); ++i) {
    hil::bench::ReversalSummary r;
    r.stall_s = stall_s[i];
    if (i < gap_est_true.size()) std::tie(r.gap_est_deg, r.gap_true_deg) = gap_est_true[i];
    s.reversals.push_back(r);
  }
  s.iae_mpa_s = 1.25;
  return s;
}

TEST(RunChecks, MetricsOverReversalsAndAgainstTheNoneRun) {
  const Campaign c = campaign_with(
      "- {name: cut_each, runs: [run], metric: stall_vs_none, from_reversal: 2, to_reversal: 3, reduce: max, max: 0.4}\n"
      "- {name: cut_mean, runs: [run], metric: stall_vs_none, from_reversal: 2, max: 0.5}\n"
      "- {name: gap, runs: [run], metric: gap_error_rel, reduce: max, max: 0.2}\n"
      "- {name: iae, metric: iae_mpa_s, min: 1, max: 1.5}\n"
      "- {name: trips, metric: interlock_trips, max: 0}\n"
      "- {name: late, runs: [run], metric: stall_s_per_reversal, from_reversal: 9, max: 1}\n");
  const RunSummary none = summary_with({1.0, 1.0, 1.0, 0.5});
  const RunSummary run = summary_with({1.0, 0.5, 0.1, 0.2}, {{0, 1}, {1.1, 1}, {1.5, 2}, {2.1, 2}});
  RunChecks checks(c, "run");
  const auto other = [&](const std::string& name) { return name == "none" ? &none : nullptr; };
  const auto results = checks.finish(run, 2, other);
  ASSERT_EQ(results.size(), 6u);
  // Per reversal 2..3: 0.5 / 1 and 0.1 / 1, the worst 0.5.
  EXPECT_NEAR(find(results, "cut_each").value, 0.5, 1e-12);
  EXPECT_EQ(find(results, "cut_each").verdict, Verdict::fail);
  // Mean over 2..4: (0.5 + 0.1 + 0.2) / 3 over (1 + 1 + 0.5) / 3.
  EXPECT_NEAR(find(results, "cut_mean").value, 0.8 / 2.5, 1e-12);
  EXPECT_EQ(find(results, "cut_mean").verdict, Verdict::pass);
  // From the 2nd reversal by default: 0.1 / 1, 0.5 / 2, 0.1 / 2; the worst 0.25.
  EXPECT_NEAR(find(results, "gap").value, 0.25, 1e-12);
  EXPECT_EQ(find(results, "gap").verdict, Verdict::fail);
  EXPECT_EQ(find(results, "iae").verdict, Verdict::pass);
  EXPECT_EQ(find(results, "trips").value, 2);
  EXPECT_NE(find(results, "trips").message.find("interlock_trips = 2 > max 0"), std::string::npos);
  EXPECT_EQ(find(results, "late").verdict, Verdict::skipped);
  EXPECT_NE(find(results, "late").message.find("has 4 reversals"), std::string::npos);
  // Without the none run (a served run started alone): unknown, skipped, not failed.
  const auto alone = checks.finish(run, 0, {});
  EXPECT_EQ(find(alone, "cut_mean").verdict, Verdict::skipped);
  // A check with `runs:` applies to those runs only: the none run has iae and trips.
  RunChecks none_checks(c, "none");
  EXPECT_EQ(none_checks.finish(none, 0, {}).size(), 2u);
  // A rig without the valve angle: the stall is NaN, the check skipped, not failed.
  const auto no_valve = checks.finish(summary_with({NAN, NAN, NAN, NAN}), 0, other);
  EXPECT_EQ(find(no_valve, "cut_each").verdict, Verdict::skipped);
  const auto tally = hil::bench::tally(results);
  EXPECT_EQ(tally.passed, 2);
  EXPECT_EQ(tally.failed, 3);
  EXPECT_EQ(tally.skipped, 1);
}

}  // namespace
