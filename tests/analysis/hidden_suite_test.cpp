// The hidden-effect suite's criteria on a handful of its files (issue 37, acceptance 1; the whole
// suite: hil_hidden_suite, tests/analysis/run_hidden_suite.sh, results in analysis/README.md):
// healthy files at the ends of the suite's noise colours and levels say nothing_missing and add
// nothing; files with one, two and three hidden effects are found in full (exactly the hidden
// candidates, each parameter within 15 %), after the premise that each is identifiable on its file
// (each effect's absence from the true model costs at least half the noise power).
#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <vector>

#include "hidden_suite.hpp"
#include "temp_file.hpp"

namespace {

using namespace hil::test::suite;

void print(const Score& s) {
  std::printf(
      "[ suite ] %s: %s, %s, %s, encoder %s, %s %.1f kPa: %s, found %s; %s (fit %.2f / %.2f %%, floor %.2f %%, drop "
      "cost %.1f, %.1f s)\n",
      s.name.c_str(), s.effects.c_str(), s.logger.c_str(), s.reference.c_str(), s.encoder ? "yes" : "no", s.colour.c_str(),
      s.level_kpa, s.verdict.c_str(), s.found.empty() ? "-" : s.found.c_str(), s.params.c_str(), s.fit_before_pct,
      s.fit_after_pct, s.floor_pct, s.min_drop_cost, s.wall_s);
}

// No false alarm at the suite's noise extremes: the least and most coloured, the lowest and
// highest level, through the bench's telemetry and a DAQ (1 kPa ADC steps, jitter, holes).
TEST(HiddenSuite, HealthyFilesAtTheNoiseExtremesSayNothingMissing) {
  hil::test::TempDir dir;
  const std::vector<SuiteFile> files = {
      draw_file(3701, "healthy_ar08_5kpa", {}, "AR(1) phi 0.8", 5.0, Logger::bench),
      draw_file(3702, "healthy_50hz_1kpa", {}, "filter 50 Hz", 1.0, Logger::bench),
      // 2.5 kPa of AR(1) noise in 1 kPa steps was read as white, 2.0 kPa: `unexplained` before.
      draw_file(3703, "healthy_daq_ar03", {}, "AR(1) phi 0.3", 2.5, Logger::daq),
      // 1 kPa behind a 50 Hz filter in 1 kPa steps was read as white, 0.64 kPa for 1.08:
      // `unexplained` before (every healthy DAQ file at 1 kPa of seeds 37 and 38).
      draw_file(3704, "healthy_daq_50hz_1kpa", {}, "filter 50 Hz", 1.0, Logger::daq),
  };
  for (const auto& f : files) {
    const Score s = run_file(f, dir.path());
    print(s);
    EXPECT_EQ(s.verdict, "nothing_missing") << s.name;
    EXPECT_TRUE(s.found.empty()) << s.name << ": " << s.found;
  }
}

// One, two and three hidden effects on coloured noise, found in full.
TEST(HiddenSuite, OneTwoAndThreeEffectsAreFoundInFull) {
  hil::test::TempDir dir;
  const std::vector<SuiteFile> files = {
      draw_file(3711, "one_gap_daq", {"gap"}, "filter 100 Hz", 2.5, Logger::daq),
      draw_file(3712, "two_lag_erosion", {"lag", "erosion"}, "AR(1) phi 0.55", 2.5, Logger::bench),
      draw_file(3713, "three_gap_erosion_bias", {"gap", "erosion", "bias"}, "filter 200 Hz", 1.0, Logger::bench),
  };
  for (const auto& f : files) {
    const Score s = run_file(f, dir.path());
    print(s);
    ASSERT_TRUE(s.identifiable) << s.name << ": " << s.why_not_identifiable;
    EXPECT_TRUE(s.right_set) << s.name << ": found " << s.found << " for " << s.effects;
    EXPECT_LE(s.worst_error, 0.15) << s.name << ": " << s.params;
  }
}

}  // namespace
