// A compensator is one file: known_gap_compensator.cpp registers `test_known_gap`, and with no
// other edit a campaign selects it per run (its parameters in a block named after it), a sweep
// selects it per point, and its jumps reach the telemetry, the summary and sweep.csv.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/campaign/sim.hpp"
#include "hil/bench/campaign/sweep.hpp"
#include "hil/ctl/compensator.hpp"
#include "sweep_rows.hpp"

namespace {

using namespace hil::bench;
using hil::test::column;
using hil::test::slurp;
using hil::test::source_path;
using hil::test::TempDir;
namespace fs = std::filesystem;

// The sweep tests' 5 s campaign (four reversals, gap 1 deg drifting to 1.5 deg), noise-free, with
// a run of the test compensator at half the known gap.
std::string campaign_yaml() {
  return "name: part\nplant: " + source_path("configs/plant/nominal.yaml").string() +
         "\nduration_s: 5\nperiod_ms: 1\nseed: 3\nsensor_noise_kpa: 0\n"
         "reference:\n  initial_mpa: 1.0\n  profile:\n"
         "    - square: {from_s: 1, half_period_s: 1, low_mpa: 1.0, high_mpa: 1.4}\n"
         "gap:\n  initial_deg: 1.0\n"
         "controller:\n  test_known_gap: {jump_scale: 0.5}\n"
         "runs:\n  - name: none\n    compensation: none\n"
         "  - name: jump\n    compensation: constant\n    compensator: test_known_gap\n";
}

TEST(CompensatorPart, RegisteredFromItsOwnFileWithItsSpecs) {
  const auto names = hil::ctl::compensator_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "test_known_gap"), names.end());
  const auto* info = hil::ctl::find_compensator("test_known_gap");
  ASSERT_NE(info, nullptr);
  ASSERT_EQ(info->specs.size(), 2u);
  EXPECT_EQ(info->specs[1].key, "jump_scale");
}

TEST(CompensatorPart, CampaignRunsItWithTheParametersOfItsBlock) {
  TempDir dir;
  const Campaign c = load_campaign_text(campaign_yaml(), "part.yaml", dir.path());
  ASSERT_EQ(c.runs[1].controller.compensator, "test_known_gap");
  SimOptions options;
  options.out_dir = dir.path();
  options.progress = false;
  run_campaign(c, options);

  const auto rows = hil::test::csv_rows(slurp(dir.path() / "part/jump/telemetry.csv"));
  const std::size_t comp = column(rows[0], "comp_deg"), intention = column(rows[0], "motion_intention");
  int jumps = 0, flips = 0;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    const double jump_deg = std::stod(rows[i][comp]);
    if (i > 1 && rows[i][intention] != rows[i - 1][intention]) ++flips;
    if (jump_deg == 0) continue;
    ++jumps;
    // Half the known gap (1 deg), in the direction of the new intention.
    EXPECT_EQ(jump_deg, 0.5 * std::stoi(rows[i][intention])) << "row " << i;
  }
  EXPECT_GE(jumps, 4);      // the square wave's four reversals at least
  EXPECT_EQ(jumps, flips);  // one jump per flip of the intention, none elsewhere
  const auto summary = nlohmann::json::parse(slurp(dir.path() / "part/jump/summary.json"));
  EXPECT_EQ(summary["compensator"], "test_known_gap");
  EXPECT_EQ(summary["compensation_events"], jumps);
}

TEST(CompensatorPart, CampaignErrorsNameTheKeyAndTheRange) {
  TempDir dir;
  auto load = [&](const std::string& from, const std::string& to) {
    std::string text = campaign_yaml();
    text.replace(text.find(from), from.size(), to);
    try {
      load_campaign_text(text, "part.yaml", dir.path());
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(load("jump_scale: 0.5", "jump_scale: 3")
                .find("part.yaml:14:20: controller.test_known_gap.jump_scale: the jump, "
                      "as a fraction of the known gap: must be in [0, 2]"),
            std::string::npos)
      << load("jump_scale: 0.5", "jump_scale: 3");
  EXPECT_NE(load("jump_scale: 0.5", "jump_scal: 0.5").find("did you mean 'jump_scale'"), std::string::npos);
  EXPECT_NE(load("compensator: test_known_gap", "compensator: test_known").find("must be a registered compensator: paper, "),
            std::string::npos);
  EXPECT_NE(load("compensator: test_known_gap", "compensator: test_known_gap\n    observer: paper")
                .find("give 'compensator' or its older name 'observer', not both"),
            std::string::npos);
}

// Per point: the run's compensator and the test compensator's parameter are sweep axes.
TEST(CompensatorPart, SweepSelectsItPerPoint) {
  TempDir dir;
  const fs::path campaign = dir.write("part.yaml", campaign_yaml());
  const fs::path sweep = dir.write("parts.yaml", "name: parts\ncampaign: " + campaign.string() +
                                                     "\nruns: [none, jump]\naxes:\n"
                                                     "  - path: campaign.runs[1].compensator\n"
                                                     "    values: [test_known_gap, robust]\n"
                                                     "  - path: controller.test_known_gap.jump_scale\n"
                                                     "    values: [0, 1]\n");
  const auto rows = hil::test::run_sweep_rows(dir, sweep, 4);
  ASSERT_FALSE(rows.empty());
  const std::size_t who = column(rows[0], "campaign.runs[1].compensator"),
                    scale = column(rows[0], "controller.test_known_gap.jump_scale"),
                    ratio = column(rows[0], "jump.stall_vs_none"), gap = column(rows[0], "jump.gap_error_deg");
  std::map<std::string, std::map<std::string, double>> stall_vs_none;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    stall_vs_none[rows[i][who]][rows[i][scale]] = std::stod(rows[i][ratio]);
    // The test compensator's estimate is the known gap: off by the drift (none here).
    if (rows[i][who] == "test_known_gap") {
      EXPECT_NEAR(std::stod(rows[i][gap]), 0, 1e-9);
    }
  }
  // No jump: the command of the `none` run exactly, so exactly its stall.
  EXPECT_EQ(stall_vs_none["test_known_gap"]["0"], 1.0);
  // The whole known gap at each reversal: most of the stall is gone.
  EXPECT_LT(stall_vs_none["test_known_gap"]["1"], 0.5);
  // The other compensator's parameter does not touch the robust one.
  EXPECT_EQ(stall_vs_none["robust"]["0"], stall_vs_none["robust"]["1"]);
  EXPECT_NE(stall_vs_none["robust"]["1"], stall_vs_none["test_known_gap"]["1"]);
}

}  // namespace
