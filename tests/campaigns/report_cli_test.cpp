// `hilbench report` as a user runs it on a run folder `hilbench serve` left: an --out that is one
// of the run's own files, a config snapshot in run.json that does not load, telemetry whose
// observer states are no codes. Each is refused naming where, and the run is left as it was.
#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "support/run_command.hpp"
#include "support/run_folder.hpp"
#include "support/temp_file.hpp"

using hil::test::hilbench;
using hil::test::run_command;
using hil::test::slurp;
using hil::test::source_path;

namespace {

namespace fs = std::filesystem;

const std::string kCampaignYaml = "name: review\nplant: " + source_path("configs/plant/nominal.yaml").string() +
                                  "\nduration_s: 1\n"
                                  "reference: {initial_mpa: 1.0, profile: [{step: {at_s: 0.3, to_mpa: 1.2}}]}\n"
                                  "runs:\n  - {name: adaptive, compensation: adaptive}\n";

// A run folder with run.json (kCampaignYaml's run, its campaign file named `campaign_file`) and a
// telemetry.csv of 1 s at 1 kHz whose touch_state cell on file line `bad_line` is `bad_touch`.
fs::path recorded_run(const hil::test::TempDir& dir, const fs::path& campaign_file, std::size_t bad_line = 0,
                      const std::string& bad_touch = "") {
  const fs::path run = dir.path() / "20261127T050000Z_review_adaptive";
  hil::test::write_ended_run(run, "review", "adaptive", kCampaignYaml, campaign_file, 1);
  std::string csv = "t_s,theta_cmd_deg,p_meas_mpa,theta_motor_deg,p_ref_mpa,touch_state,motion_intention\n";
  for (std::size_t k = 0; k < 1000; ++k) {
    const std::string touch = k + 2 == bad_line ? bad_touch : "1";
    csv += std::to_string(k * 1e-3) + ",10.0,1.0,10.0,1.0," + touch + ",0\n";
  }
  std::ofstream(run / "telemetry.csv") << csv;
  return run;
}

// An --out that is a file of a run the report reads (under any spelling) would replace it with
// HTML: refused before anything is read, the run left whole. The run's own report.html is the
// report's to replace.
TEST(Cli, ReportRefusesAnOutThatIsOneOfTheRunsOwnFiles) {
  hil::test::TempDir dir;
  const fs::path run = recorded_run(dir, dir.path() / "review.yaml");
  std::ofstream(run / "events.jsonl") << "{\"t_s\": 0, \"event\": \"start\"}\n";
  fs::create_directories(run / "analyses/a1");
  std::ofstream(run / "analyses/a1/compare.json") << "{}\n";
  const fs::path link = dir.path() / "record.json";
  fs::create_symlink(run / "run.json", link);
  const std::vector<std::pair<fs::path, fs::path>> refused = {
      {run / "run.json", run / "run.json"},         {run / "telemetry.csv", run / "telemetry.csv"},
      {run / "events.jsonl", run / "events.jsonl"}, {run / "analyses/a1/compare.json", run / "analyses/a1/compare.json"},
      {run / "." / "run.json", run / "run.json"},   {link, run / "run.json"},
  };
  const std::string record = slurp(run / "run.json"), telemetry = slurp(run / "telemetry.csv");
  for (const auto& [out, input] : refused) {
    const auto r = run_command(hilbench() + " report " + run.string() + " --out " + out.string() + " --quiet");
    EXPECT_EQ(r.status, 1) << out << "\n" << r.output;
    EXPECT_NE(r.output.find("--out " + out.string() + ": is the input " + input.string() + ", which it would overwrite"),
              std::string::npos)
        << r.output;
  }
  auto r = run_command(hilbench() + " report " + run.string() + " --out " + run.string() + " --quiet");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("--out " + run.string() + ": is a folder; give the report's file name"), std::string::npos) << r.output;
  // (compared as a bool: a run.json replaced by the report would print the whole HTML)
  EXPECT_TRUE(slurp(run / "run.json") == record) << "run.json was replaced";
  EXPECT_TRUE(slurp(run / "telemetry.csv") == telemetry) << "telemetry.csv was replaced";
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_FALSE(fs::exists(run / "report.html"));

  // The run's report itself, the default and said by name, is made (and made again).
  for (const std::string& out : {std::string(), " --out " + (run / "report.html").string()}) {
    r = run_command(hilbench() + " report " + run.string() + out + " --quiet");
    EXPECT_EQ(r.status, 0) << r.output;
    EXPECT_TRUE(fs::exists(run / "report.html"));
  }
  EXPECT_TRUE(slurp(run / "run.json") == record) << "run.json was replaced";
}

// A run.json whose campaign or plant snapshot does not load: the error names the copy in run.json
// (its key, and of which file it is the copy), whose line and column they are, not the file on
// disk, which may be fine.
TEST(Cli, ReportNamesABadConfigSnapshotAsTheCopyInRunJson) {
  hil::test::TempDir dir;
  const fs::path campaign_file = source_path("configs/campaigns/paper_adaptive.yaml");
  const fs::path run = recorded_run(dir, campaign_file);
  auto record = hil::bench::read_run_record(run);
  record.config.campaign_yaml = "name: [review\n";
  hil::bench::write_run_record(run, record);
  auto r = run_command(hilbench() + " report " + run.string() + " --quiet");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("hilbench report: " + (run / "run.json").string() + ": config.campaign_yaml:"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("(config.campaign_yaml is the copy of " + campaign_file.string() + " that run.json keeps"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find(": " + campaign_file.string() + ":"), std::string::npos) << r.output;

  const fs::path plant_file = source_path("configs/plant/nominal.yaml");
  record.config.campaign_yaml = kCampaignYaml;
  record.config.plant_file = plant_file.string();
  record.config.plant_yaml = "effects: {backlash: [\n";
  hil::bench::write_run_record(run, record);
  r = run_command(hilbench() + " report " + run.string() + " --quiet");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("hilbench report: " + (run / "run.json").string() + ": config.plant_yaml:"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("(config.plant_yaml is the copy of " + plant_file.string() + " that run.json keeps"), std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(run / "report.html"));
}

// touch_state and motion_intention are the observer's codes -1, 0, 1: any other value is refused
// with its place (1e300 was converted to an int unchecked, undefined behaviour, and reported).
TEST(Cli, ReportRefusesAnObserverStateThatIsNoCode) {
  for (const char* bad : {"1e300", "-1e300", "0.5", "2"}) {
    hil::test::TempDir dir;
    const fs::path run = recorded_run(dir, dir.path() / "review.yaml", 502, bad);
    const auto r = run_command(hilbench() + " report " + run.string() + " --quiet");
    EXPECT_EQ(r.status, 1) << bad << "\n" << r.output;
    EXPECT_NE(r.output.find((run / "telemetry.csv").string() + ":502:6: column 'touch_state': must be -1, 0 or 1"),
              std::string::npos)
        << bad << "\n"
        << r.output;
    EXPECT_FALSE(fs::exists(run / "report.html")) << bad;
  }
}

}  // namespace
