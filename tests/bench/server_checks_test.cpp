// A campaign's checks on a served run: the real `hilbench serve` runs a campaign with a checks
// block, and each run's run.json (and the status's last campaign) carries the same verdicts as
// `hilbench sim`'s evaluator gives on the same campaign.
#include <gtest/gtest.h>

#include <algorithm>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/campaign/sim.hpp"
#include "hil/bench/rt/run_record.hpp"
#include "server_process.hpp"

using namespace std::chrono_literals;
using nlohmann::json;

namespace {

// Checks that pass with a wide margin, one that cannot pass, one against the `none` run of the
// same start, and a signal window.
const char* kChecks =
    "checks:\n"
    "  - {name: stall_cut, runs: [adaptive], metric: stall_vs_none, from_reversal: 2, max: 0.5}\n"
    "  - {name: impossible_iae, runs: [adaptive], metric: iae_mpa_s, max: 0.0001}\n"
    "  - {name: no_safe_state, signal: safe_state, max: 0}\n"
    "  - {name: settles, signal: pressure_error_rel, after: reference_change, delay_s: 0.8, max: 0.2}\n";

TEST(ServerChecks, RunJsonCarriesTheSimsVerdicts) {
  hil::test::ServerProcess server;
  const auto api = server.client();
  const std::string yaml = hil::test::short_campaign_yaml(4, "verdicts") + kChecks;
  ASSERT_EQ(api.request("POST", "/api/start", json{{"campaign_yaml", yaml}, {"speed", 10}}.dump(), "application/json").status,
            202);
  const json s = hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "idle"; }, 60s);
  ASSERT_EQ(s["last"]["outcome"], "completed") << s.dump(2);

  // What `hilbench sim` says of the same campaign.
  const auto campaign = hil::bench::load_campaign_text(yaml, "verdicts.yaml", hil::test::source_path("configs/campaigns"));
  hil::test::TempDir out;
  hil::bench::SimOptions options;
  options.out_dir = out.path();
  options.telemetry = false;
  options.progress = false;
  const auto sim = hil::bench::run_campaign(campaign, options);

  std::vector<std::filesystem::path> dirs;
  for (const auto& e : std::filesystem::directory_iterator(server.runs_dir()))
    if (e.is_directory()) dirs.push_back(e.path());
  ASSERT_EQ(dirs.size(), 2u);
  ASSERT_EQ(s["last"]["runs"].size(), 2u);
  for (std::size_t i = 0; i < dirs.size(); ++i) {
    const hil::bench::RunRecord record = hil::bench::read_run_record(dirs[i]);
    const auto& expected = std::find_if(sim.runs.begin(), sim.runs.end(), [&](const auto& r) { return r.name == record.run; });
    ASSERT_NE(expected, sim.runs.end()) << record.run;
    const json& got = record.checks;
    ASSERT_TRUE(got.is_object()) << record.run;
    ASSERT_EQ(got["results"].size(), expected->checks.size()) << got.dump(1);
    for (std::size_t k = 0; k < expected->checks.size(); ++k) {
      const auto& want = expected->checks[k];
      const json& r = got["results"][k];
      EXPECT_EQ(r["check"], want.check);
      EXPECT_EQ(r["verdict"], hil::bench::to_string(want.verdict)) << record.run << "/" << want.check << ": " << r.dump();
      ASSERT_TRUE(r["value"].is_number()) << r.dump();
      EXPECT_NEAR(r["value"].get<double>(), want.value, 0.05 * std::abs(want.value) + 1e-6) << record.run << "/" << want.check;
    }
    // The status's last campaign carries the same verdicts per run.
    const auto run_in_status =
        std::find_if(s["last"]["runs"].begin(), s["last"]["runs"].end(), [&](const json& r) { return r["run"] == record.run; });
    ASSERT_NE(run_in_status, s["last"]["runs"].end());
    EXPECT_EQ((*run_in_status)["checks"], got);
  }
  // The adaptive run: its stall against the none run of the same start passed, the IAE failed.
  // (Folders are named by the start's second, then the run: found by their record, not sorted.)
  const auto adaptive_dir =
      std::find_if(dirs.begin(), dirs.end(), [](const auto& d) { return hil::bench::read_run_record(d).run == "adaptive"; });
  ASSERT_NE(adaptive_dir, dirs.end());
  const hil::bench::RunRecord adaptive = hil::bench::read_run_record(*adaptive_dir);
  EXPECT_EQ(adaptive.checks["failed"], 1);
  EXPECT_EQ(adaptive.checks["passed"], 3);
  EXPECT_EQ(adaptive.checks["results"][0]["verdict"], "pass") << adaptive.checks.dump(1);
  EXPECT_NE(adaptive.checks["results"][1]["message"].get<std::string>().find("> max 0.0001"), std::string::npos);
}

}  // namespace
