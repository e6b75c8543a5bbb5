// `hilbench run CAMPAIGN --rig NAME` as a user runs it, without a server: on the simulated rig
// each run leaves the record a served run leaves (run.json read back by the record's own reader,
// telemetry.csv with the rig's columns, telemetry.mcap, events.jsonl), the checks' verdicts are
// in run.json, a failed check exits 3 as `hilbench sim` does, and the loop's rows are `hilbench
// sim`'s rows (one period for both). A rig that does not exist is a usage error naming it.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <regex>
#include <string>
#include <vector>

#include "hil/bench/rt/run_record.hpp"
#include "hil/bench/rt/telemetry_record.hpp"
#include "hil/csv_reader.hpp"
#include "hil/telemetry_schema.hpp"
#include "support/run_command.hpp"
#include "support/temp_file.hpp"

using hil::test::hilbench;
using hil::test::run_command;
using hil::test::slurp;
using hil::test::source_path;

namespace {

std::string q(const std::filesystem::path& p) {
  std::string quoted(1, '\'');
  quoted.append(p.string()).push_back('\'');
  return quoted;
}

// Two runs of 1.5 s (1 500 periods each): a check that passes, one that cannot.
std::filesystem::path short_campaign(const hil::test::TempDir& dir) {
  return dir.write("cli_run.yaml",
                   "name: cli_run\n"
                   "plant: " +
                       source_path("configs/plant/nominal.yaml").string() +
                       "\n"
                       "duration_s: 1.5\n"
                       "period_ms: 1\n"
                       "seed: 3\n"
                       "sensor_noise_kpa: 2.0\n"
                       "reference:\n"
                       "  initial_mpa: 1.0\n"
                       "  profile:\n"
                       "    - square: {from_s: 0.3, half_period_s: 0.5, low_mpa: 1.0, high_mpa: 1.5}\n"
                       "gap:\n"
                       "  initial_deg: 1.0\n"
                       "runs:\n"
                       "  - name: none\n"
                       "    compensation: none\n"
                       "  - name: adaptive\n"
                       "    compensation: adaptive\n"
                       "    initial_gap_deg: 0\n"
                       "checks:\n"
                       "  - {name: no_safe_state, signal: safe_state, max: 0}\n"
                       "  - {name: impossible_iae, runs: [adaptive], metric: iae_mpa_s, max: 0.0001}\n");
}

std::vector<std::filesystem::path> run_dirs(const std::filesystem::path& out) {
  std::vector<std::filesystem::path> dirs;
  for (const auto& e : std::filesystem::directory_iterator(out))
    if (e.is_directory()) dirs.push_back(e.path());
  return dirs;
}

TEST(RunCli, SimRigRunsAreRecordedAsServedRunsWithTheirVerdicts) {
  hil::test::TempDir dir;
  const auto campaign = short_campaign(dir);
  const auto out = dir.path() / "runs";
  const auto r = run_command(hilbench() + " run " + q(campaign) + " --rig sim --configs " + q(source_path("configs")) +
                             " --out " + q(out) + " --speed 100 --no-mlock");
  // The impossible check failed, every run completed: 3, as `hilbench sim` exits.
  ASSERT_EQ(r.status, 3) << r.output;
  EXPECT_NE(r.output.find("fail    adaptive/impossible_iae"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("cli_run/none: completed"), std::string::npos) << r.output;

  const auto dirs = run_dirs(out);
  ASSERT_EQ(dirs.size(), 2u);
  // The loop's rows as `hilbench sim` writes them for the same campaign (its first columns).
  const auto sim_out = dir.path() / "sim";
  const auto s = run_command(hilbench() + " sim " + q(campaign) + " --quiet --out " + q(sim_out));
  ASSERT_EQ(s.status, 3) << s.output;
  for (const auto& d : dirs) {
    const hil::bench::RunRecord record = hil::bench::read_run_record(d);
    SCOPED_TRACE(record.run);
    EXPECT_EQ(record.outcome, hil::bench::Outcome::completed);
    EXPECT_TRUE(record.ended);
    EXPECT_EQ(record.campaign, "cli_run");
    EXPECT_EQ(record.rig_kind, "sim");
    EXPECT_EQ(record.periods_run, 1500);
    ASSERT_TRUE(record.telemetry.has_value());
    EXPECT_EQ(record.telemetry->rows_written, 1500u);
    ASSERT_TRUE(record.checks.is_object());
    EXPECT_EQ(record.checks["failed"], record.run == "adaptive" ? 1 : 0) << record.checks.dump(1);
    EXPECT_EQ(record.checks["results"][0]["verdict"], "pass") << record.checks.dump(1);
    EXPECT_TRUE(std::filesystem::exists(d / "telemetry.mcap"));
    EXPECT_FALSE(std::filesystem::exists(d / ".lock"));     // released at the end
    EXPECT_FALSE(std::filesystem::exists(d / ".reserve"));  // given back for the final run.json
    const std::string events = slurp(d / "events.jsonl");
    EXPECT_NE(events.find("\"kind\":\"run_start\""), std::string::npos);
    EXPECT_NE(events.find("\"kind\":\"loop_start\""), std::string::npos);

    // telemetry.csv: every column of the schema (the sim rig knows the truth), 1 500 rows, and
    // the simulation's columns equal to `hilbench sim`'s row for row, as printed.
    std::vector<std::string> names;
    for (const auto& c : hil::bench::telemetry_columns(hil::bench::ColumnSet::all)) names.push_back(c.name);
    hil::CsvHeader header;
    const auto served = hil::read_csv(d / "telemetry.csv", {names, {}, "t_s"}, &header);
    ASSERT_EQ(served.rows(), 1500u);
    const auto simulated =
        hil::read_csv(sim_out / "cli_run" / record.run / "telemetry.csv",
                      {std::vector<std::string>(names.begin(), names.begin() + hil::telemetry::kSimColumns), {}, "t_s"});
    ASSERT_EQ(simulated.rows(), served.rows());
    for (std::size_t c = 0; c < hil::telemetry::kSimColumns; ++c) {
      for (std::size_t i = 0; i < served.rows(); ++i) {
        ASSERT_EQ(served.values[c][i], simulated.values[c][i]) << names[c] << " row " << i;
      }
    }
  }
}

TEST(RunCli, AnUnknownRigIsAUsageErrorNamingIt) {
  hil::test::TempDir dir;
  const auto campaign = short_campaign(dir);
  const auto r = run_command(hilbench() + " run " + q(campaign) + " --rig hybird --configs " + q(source_path("configs")) +
                             " --out " + q(dir.path() / "runs"));
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_NE(r.output.find("--rig hybird"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("did you mean 'hybrid'?"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "runs"));  // nothing made before the inputs are good
}

}  // namespace
