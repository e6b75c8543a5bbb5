// `hilbench sim` as a user runs it: the files it writes, and what it does with bad input.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "hil/csv_reader.hpp"
#include "support/run_command.hpp"
#include "support/temp_file.hpp"

using hil::test::hilbench;
using hil::test::run_command;
using hil::test::slurp;
using hil::test::source_path;

namespace {

TEST(SimCli, PaperAdaptiveWritesTelemetrySummariesAndReport) {
  hil::test::TempDir out;
  const auto r = run_command(hilbench() + " sim " + source_path("configs/campaigns/paper_adaptive.yaml").string() + " --out " +
                             out.path().string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("report: "), std::string::npos);
  const auto dir = out.path() / "paper_adaptive";
  EXPECT_TRUE(std::filesystem::exists(dir / "report.html"));
  EXPECT_TRUE(std::filesystem::exists(dir / "campaign.yaml"));
  for (const char* run : {"none", "adaptive", "adaptive_paper"}) {
    // The telemetry is a measurement file (physics.md section 4) plus the internals.
    hil::CsvHeader header;
    const auto data = hil::read_csv(dir / run / "telemetry.csv",
                                    {{"t_s", "theta_cmd_deg", "p_meas_mpa"},
                                     {"theta_motor_deg", "p_ref_mpa", "theta_valve_deg", "gap_true_deg", "touch_state",
                                      "motion_intention", "comp_deg", "gap_est_deg"},
                                     "t_s"},
                                    &header);
    EXPECT_EQ(data.rows(), 18000u) << run;
    for (bool present : header.present) EXPECT_TRUE(present) << run;
    EXPECT_NEAR(data.values[0].back(), 17.999, 1e-9);
    EXPECT_NEAR(data.values[6].back(), 2.0, 1e-9);  // the gap grew to 2 deg at 12 s
    EXPECT_NEAR(data.values[6].front(), 1.0, 1e-9);
    const auto summary = nlohmann::json::parse(slurp(dir / run / "summary.json"));
    for (const char* key : {"iae_mpa_s", "stall_s_per_reversal", "gap_est_final_deg", "gap_true_final_deg", "touch_state_changes",
                            "compensation_events"}) {
      EXPECT_TRUE(summary.contains(key)) << run << " " << key;
    }
    EXPECT_EQ(summary["stall_s_per_reversal"].size(), 7u);  // reversals at 2.5, 5, ..., 17.5 s
  }
  // Nothing half-finished is left beside it.
  for (const auto& e : std::filesystem::directory_iterator(out.path())) EXPECT_EQ(e.path().filename(), "paper_adaptive");
}

TEST(SimCli, BadCampaignWritesNothingAndKeepsThePreviousOutput) {
  hil::test::TempDir out;
  const auto good = run_command(hilbench() + " sim " + source_path("configs/campaigns/paper_fig6.yaml").string() +
                                " --no-telemetry --quiet --out " + out.path().string());
  ASSERT_EQ(good.status, 0) << good.output;
  const auto before = slurp(out.path() / "paper_fig6" / "none" / "summary.json");
  std::string text = slurp(source_path("configs/campaigns/paper_fig6.yaml"));
  text.replace(text.find("high_mpa: 1.5"), 13, "high_mpa: 9.0");
  text.replace(text.find("../plant/nominal.yaml"), 21, source_path("configs/plant/nominal.yaml").string());
  const auto bad = out.write("in/paper_fig6.yaml", text);
  const auto r = run_command(hilbench() + " sim " + bad.string() + " --out " + out.path().string());
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("paper_fig6.yaml:14:"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("high_mpa"), std::string::npos) << r.output;
  EXPECT_EQ(slurp(out.path() / "paper_fig6" / "none" / "summary.json"), before);
}

TEST(SimCli, UsageErrorsSuggest) {
  auto r = run_command(hilbench() + " simm x.yaml");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("did you mean 'sim'"), std::string::npos) << r.output;
  r = run_command(hilbench() + " sim " + source_path("configs/campaigns/paper_fig6.yaml").string() + " --outt /tmp/x");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("did you mean --out"), std::string::npos) << r.output;
  r = run_command(hilbench() + " sim /no/such/campaign.yaml");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("/no/such/campaign.yaml: cannot open"), std::string::npos) << r.output;
  // An output folder that is a file: the path first, the reason, what was being done.
  hil::test::TempDir dir;
  const auto file = dir.write("a_file", "not a folder\n");
  const auto sweep = dir.write("sweep.yaml", "campaign: " + source_path("tests/sweep/data/tiny_campaign.yaml").string() +
                                                 "\naxes:\n  - path: campaign.seed\n    values: [1]\n");
  for (const std::string& cmd :
       {" sim " + source_path("configs/campaigns/paper_fig6.yaml").string(), " sweep " + sweep.string()}) {
    r = run_command(hilbench() + cmd + " --quiet --out " + file.string());
    EXPECT_EQ(r.status, 1) << cmd;
    EXPECT_NE(r.output.find(": error: " + file.string() + ": Not a directory (cannot create directories)"), std::string::npos)
        << cmd << "\n"
        << r.output;
    EXPECT_EQ(slurp(file), "not a folder\n");
  }
  // An override outside the sensor's range is the option's error, not the campaign's.
  r = run_command(hilbench() + " sim " + source_path("configs/campaigns/paper_fig6.yaml").string() +
                  " --sensor-noise-kpa 6e16 --out /tmp/x");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("--sensor-noise-kpa 6e16: pressure_sensor.noise_rms_kpa = 6e+16: must be in [0, 10000]"),
            std::string::npos)
      << r.output;
}

// What a command prints is its result: a full disk (or a closed pipe) that took none of it is a
// failure with the reason, not rc 0 and an empty file. An empty or option-like --out is refused.
TEST(Cli, AnOutputThatCannotBeWrittenFailsTheCommand) {
  auto r = run_command("sh -c '" + hilbench() + " effects > /dev/full'");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("hilbench effects: error: cannot write the standard output: No space left on device"),
            std::string::npos)
      << r.output;
  r = run_command(hilbench() + " sim " + source_path("configs/campaigns/paper_constant.yaml").string() + " --out= --quiet");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_NE(r.output.find("--out: needs a path, got the option '--quiet'"), std::string::npos) << r.output;
}

// characterise --readme on a symbolic link (a README kept elsewhere) updates the file it points
// to and keeps the link; it used to put a plain file in the link's place.
TEST(Cli, CharacteriseUpdatesTheReadmeALinkPointsTo) {
  hil::test::TempDir dir;
  const auto campaigns = source_path("configs/campaigns").string();
  const auto table = run_command(hilbench() + " characterise --campaigns " + campaigns);
  ASSERT_EQ(table.status, 0) << table.output;
  const auto real = dir.write("real.md", "# Title\n<!-- characterise:begin -->\nold\n<!-- characterise:end -->\nafter\n");
  const auto link = dir.path() / "link.md";
  std::filesystem::create_symlink(real, link);
  const auto r = run_command(hilbench() + " characterise --campaigns " + campaigns + " --readme " + link.string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(std::filesystem::is_symlink(link));
  EXPECT_EQ(slurp(real), "# Title\n<!-- characterise:begin -->\n" + table.output + "<!-- characterise:end -->\nafter\n");
}

TEST(SimCli, NoiseFreeOverrideAndRunSelection) {
  hil::test::TempDir out;
  const auto r = run_command(hilbench() + " sim " + source_path("configs/campaigns/paper_constant.yaml").string() +
                             " --sensor-noise-kpa 0 --runs constant --quiet --out " + out.path().string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_FALSE(std::filesystem::exists(out.path() / "paper_constant" / "none"));
  const auto data =
      hil::read_csv(out.path() / "paper_constant" / "constant" / "telemetry.csv", {{"p_meas_mpa"}, {"p_chamber_mpa"}, ""});
  for (std::size_t i = 0; i < data.rows(); i += 97) ASSERT_NEAR(data.values[0][i], data.values[1][i], 1e-6);
}

}  // namespace

namespace {
// Every sub-command answers --help with its usage and options on stdout and exit 0; the top level
// lists them all, one line each.
TEST(Cli, EverySubCommandAnswersHelp) {
  const auto top = run_command(hilbench() + " --help");
  ASSERT_EQ(top.status, 0) << top.output;
  // Each command with text its help must show: an option of its own (drive and ctl: a command).
  const std::vector<std::pair<std::string, std::vector<std::string>>> commands = {
      {"sim", {"--out", "--sensor-noise-kpa", "--no-telemetry"}},
      {"sweep", {"SWEEP.yaml", "--jobs", "--shard", "--aggregate", "--slurm", "--status"}},
      {"effects", {"usage: hilbench effects"}},
      {"serve", {"--listen", "--token", "--max-body-kb"}},
      {"ctl", {"--server", "status", "inject", "telemetry"}},
      {"compare", {"--model", "--data"}},
      {"diagnose", {"--model", "--data", "--threads", "--write-model"}},
      {"plant", {"--campaign", "--can", "--modbus", "--period-ms"}},
      {"report", {"RUN_DIR", "--out"}},
      {"drive", {"probe"}},
      {"characterise", {"--readme", "--campaigns"}},
  };
  for (const auto& [cmd, expected] : commands) {
    EXPECT_NE(top.output.find("\n  " + cmd + " "), std::string::npos) << cmd << "\n" << top.output;
    for (const char* flag : {"--help", "-h"}) {
      const auto r = run_command(hilbench() + " " + cmd + " " + flag);
      EXPECT_EQ(r.status, 0) << cmd << " " << flag << "\n" << r.output;
      EXPECT_NE(r.output.find("hilbench " + cmd), std::string::npos) << cmd << "\n" << r.output;
      EXPECT_EQ(r.output.find("unknown option"), std::string::npos) << cmd << "\n" << r.output;
      for (const auto& e : expected) EXPECT_NE(r.output.find(e), std::string::npos) << cmd << ": no " << e << "\n" << r.output;
    }
  }
  // Commands of commands answer too.
  for (const char* cmd : {"ctl start", "ctl inject sensor", "drive probe"}) {
    const auto r = run_command(hilbench() + " " + cmd + " --help");
    EXPECT_EQ(r.status, 0) << cmd << "\n" << r.output;
    EXPECT_NE(r.output.find(std::string("usage: hilbench ") + cmd), std::string::npos) << cmd << "\n" << r.output;
  }
  // No command: the usage on stderr, exit 2.
  const auto bare = run_command(hilbench());
  EXPECT_EQ(bare.status, 2);
  EXPECT_NE(bare.output.find("usage: hilbench"), std::string::npos) << bare.output;
  // (appended, not "(" + ...: GCC 12 warns falsely of an overlapping copy in that operator+)
  EXPECT_EQ(run_command(std::string("(").append(hilbench()).append(" 2>/dev/null)")).output, "");
  const auto typo = run_command(hilbench() + " sim --outt x");
  EXPECT_EQ(typo.status, 2);
  EXPECT_NE(typo.output.find("did you mean --out?"), std::string::npos) << typo.output;
}

// An option given twice: the last one counts (wrappers append their overrides); --name=value works.
TEST(Cli, TheLastOfARepeatedOptionCounts) {
  const auto r = run_command(hilbench() + " sim " + source_path("configs/campaigns/paper_fig6.yaml").string() +
                             " --sensor-noise-kpa=6e16 --sensor-noise-kpa 7e16 --out /tmp/x");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("--sensor-noise-kpa 7e16: "), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("6e16"), std::string::npos) << r.output;
  const auto bad =
      run_command(hilbench() + " sim " + source_path("configs/campaigns/paper_fig6.yaml").string() + " --sensor-noise-kpa=-1");
  EXPECT_EQ(bad.status, 2);
  EXPECT_NE(bad.output.find("--sensor-noise-kpa: cannot be negative, got -1"), std::string::npos) << bad.output;
}
}  // namespace
