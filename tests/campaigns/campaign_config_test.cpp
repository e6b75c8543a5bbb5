// Bad campaign files fail at load, naming file, line and key.
#include <gtest/gtest.h>

#include <fstream>
#include <regex>
#include <sstream>

#include "hil/bench/campaign.hpp"
#include "hil/config.hpp"
#include "support/temp_file.hpp"

namespace {

std::string paper_adaptive_text() {
  std::ifstream in(hil::test::source_path("configs/campaigns/paper_adaptive.yaml"));
  std::stringstream ss;
  ss << in.rdbuf();
  // Written to a temporary folder: point at the real plant file.
  return std::regex_replace(ss.str(), std::regex("plant: \\.\\./plant/nominal\\.yaml"),
                            "plant: " + hil::test::source_path("configs/plant/nominal.yaml").string());
}

struct Loaded {
  std::string error;
  int line = 0;  // line of the edit
};

Loaded load_with(const std::string& from, const std::string& to) {
  std::string text = paper_adaptive_text();
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  text.replace(at, from.size(), to);
  Loaded out;
  out.line = 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(at), '\n'));
  hil::test::TempDir dir;
  try {
    (void)hil::bench::load_campaign(dir.write("bad.yaml", text));
    out.error = "no error";
  } catch (const hil::cfg::Error& e) {
    out.error = e.what();
  }
  return out;
}

void expect_error(const Loaded& l, const std::string& key, const std::string& words, int line_offset = 0) {
  EXPECT_NE(l.error.find("bad.yaml:" + std::to_string(l.line + line_offset) + ":"), std::string::npos) << l.error;
  EXPECT_NE(l.error.find(key), std::string::npos) << l.error;
  EXPECT_NE(l.error.find(words), std::string::npos) << l.error;
}

TEST(CampaignConfig, TheShippedCampaignsLoad) {
  for (const char* name : {"paper_fig6", "paper_constant", "paper_adaptive", "gap_shrink", "soak_random"}) {
    const auto c = hil::bench::load_campaign(hil::test::source_path(std::string("configs/campaigns/") + name + ".yaml"));
    EXPECT_EQ(c.name, name);
    EXPECT_FALSE(c.runs.empty());
  }
}

TEST(CampaignConfig, UnknownKey) {
  expect_error(load_with("duration_s: 18", "duraton_s: 18"), "duraton_s", "did you mean 'duration_s'");
}

TEST(CampaignConfig, WrongType) {
  expect_error(load_with("duration_s: 18", "duration_s: long"), "duration_s", "expected a number, got 'long'");
}

TEST(CampaignConfig, MissingField) {
  expect_error(load_with("runs:", "rnus:"), "rnus", "unknown key 'rnus'");
  const Loaded l = load_with("  - name: none                   # the paper's original integral controller\n"
                             "    compensation: none\n",
                             "  - name: none\n");
  expect_error(l, "runs[0]", "missing required key 'compensation'");
}

TEST(CampaignConfig, PeriodMustBePositive) {
  expect_error(load_with("period_ms: 1 ", "period_ms: 0 "), "period_ms", "dT must be > 0");
}

TEST(CampaignConfig, GapCannotBeNegative) {
  expect_error(load_with("step: {at_s: 12, to_deg: 2.0}", "step: {at_s: 12, to_deg: -0.5}"), "gap.changes[0].step.to_deg",
               "a gap cannot be negative");
}

TEST(CampaignConfig, ReferenceOutsideThePlantsReach) {
  expect_error(load_with("high_mpa: 1.5", "high_mpa: 3.5"), "reference.profile[0].square.high_mpa",
               "reference 3.5 MPa is outside what the plant reaches");
}

TEST(CampaignConfig, UnknownProfileItemAndBadChoice) {
  expect_error(load_with("    - square:", "    - squares:"), "reference.profile[0]", "unknown profile item 'squares'");
  expect_error(load_with("observer: robust ", "observer: fast "), "controller.observer", "must be paper or robust");
}

TEST(CampaignConfig, ImpossiblePlantNamesThePlantFileToo) {
  hil::test::TempDir dir;
  std::ifstream in(hil::test::source_path("configs/plant/nominal.yaml"));
  std::stringstream ss;
  ss << in.rdbuf();
  std::string plant = std::regex_replace(ss.str(), std::regex("pressure_exponent: 0\\.35"), "pressure_exponent: 1.2");
  const auto plant_file = dir.write("plant/bad_plant.yaml", plant);
  std::string text = std::regex_replace(paper_adaptive_text(), std::regex("plant: [^ ]+nominal\\.yaml"),
                                        "plant: " + plant_file.string());
  try {
    (void)hil::bench::load_campaign(dir.write("c.yaml", text));
    FAIL();
  } catch (const hil::cfg::Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("c.yaml:"), std::string::npos) << msg;
    EXPECT_NE(msg.find("bad_plant.yaml:20:"), std::string::npos) << msg;
    EXPECT_NE(msg.find("effects.gas_generator.pressure_exponent"), std::string::npos) << msg;
  }
}

}  // namespace
