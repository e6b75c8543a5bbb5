// The noise suite's light sample (issue 49; the whole suite: hil_hidden_suite --noise-healthy,
// tests/analysis/run_noise_suite.sh, results in analysis/README.md): healthy files whose noise is
// an instrument's (1/f, sparse spikes, a 12-bit ADC under its steps, and one file of every class)
// say nothing_missing, add nothing, and read the noise within 25 % of what the file holds; a hidden
// effect under 1/f noise is still found in full.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "hidden_suite.hpp"
#include "temp_file.hpp"

namespace {

using namespace hil::test::suite;
using hil::test::SensorNoise;

void print(const Score& s) {
  std::printf("[ noise ] %s: %s\n", s.name.c_str(), s.noise_method.c_str());
  std::printf("[ noise ] %s: %s (%s), %s, %s: %s, found %s; noise read %.3g of %.3g kPa, spikes %zu found %zu; %s (%.1f s)\n",
              s.name.c_str(), s.noise_class.c_str(), s.colour.c_str(), s.logger.c_str(), s.reference.c_str(), s.verdict.c_str(),
              s.found.empty() ? "-" : s.found.c_str(), s.noise_read_kpa, s.noise_truth_kpa, s.spikes, s.outliers,
              s.params.c_str(), s.wall_s);
}

SuiteFile with_noise(SuiteFile f, const std::string& cls, const std::string& what, const SensorNoise& n) {
  f.noise = n;
  f.noise_class = cls;
  f.colour = what;
  return f;
}

void expect_healthy(const Score& s) {
  print(s);
  EXPECT_EQ(s.verdict, "nothing_missing") << s.name;
  EXPECT_TRUE(s.found.empty()) << s.name << ": " << s.found;
  EXPECT_NEAR(s.noise_read_kpa / s.noise_truth_kpa, 1.0, 0.25) << s.name;
}

// The three healthy files that were `unexplained` (each ratio is the issue's).
TEST(NoiseSuite, OneOverFSpikesAndACoarseADCAreNothingMissing) {
  hil::test::TempDir dir;
  const SuiteFile base = draw_file(4901, "base", {}, "AR(1) phi 0.3", 1.0, Logger::bench, 20);
  // 2.0 kPa of 1/f noise from 0.5 Hz plus 0.3 kPa white: read as 1.34 kPa of first-order noise, "1.5 times".
  SensorNoise pink{.white_kpa = 0.3, .seed = 11};
  pink.pink_kpa = 2.0;
  expect_healthy(run_file(with_noise(base, "1/f", "1/f 2.0 kPa", pink), dir.path()));
  // One row in ~2000 with 20-60 kPa of random sign on 1.5 kPa white: "1.21 times".
  SensorNoise spikes{.white_kpa = 1.5, .seed = 12};
  spikes.spike_rate = 1.0 / 2000, spikes.spike_lo_kpa = 20, spikes.spike_hi_kpa = 60;
  SuiteFile sf = with_noise(base, "spikes", "spikes", spikes);
  sf.name = "spikes";
  const Score s = run_file(sf, dir.path());
  expect_healthy(s);
  EXPECT_GE(s.outliers, s.spikes * 8 / 10) << "most spikes are found and counted";
  EXPECT_LE(s.outliers, s.spikes + 3);
  // A 12-bit ADC over 0-10 MPa (2.441 kPa steps), 0.3 kPa white under them: read as 1.59e-09 kPa.
  SensorNoise adc{.white_kpa = 0.3, .step_kpa = 1e4 / 4096, .seed = 13};
  SuiteFile af = with_noise(base, "ADC", "12-bit", adc);
  af.name = "adc12";
  expect_healthy(run_file(af, dir.path()));
}

// One healthy file of each class the whole suite passes without a false alarm (its first draw of
// seed 4902; analysis/README.md lists the classes that do not hold yet: brown, and in part 1/f at
// 250 Hz, AR(4), coarse ADCs and combinations).
TEST(NoiseSuite, AHealthyFileOfEachHeldClassIsNothingMissing) {
  hil::test::TempDir dir;
  const std::vector<std::string> held = {"white", "AR(1)", "resonant", "hum", "spikes", "filter"};
  for (const SuiteFile& f : draw_noise_suite(4902, 1, 0, 15))
    if (std::find(held.begin(), held.end(), f.noise_class) != held.end()) expect_healthy(run_file(f, dir.path()));
}

// A hidden effect under 1/f noise: the noise floor read from the residual's spectrum does not take
// the effect's misfit as noise.
TEST(NoiseSuite, AnEffectUnderOneOverFNoiseIsFoundInFull) {
  hil::test::TempDir dir;
  SensorNoise pink{.white_kpa = 0.3, .seed = 14};
  pink.pink_kpa = 2.0;
  const SuiteFile f =
      with_noise(draw_file(4903, "gap_pink", {"gap"}, "AR(1) phi 0.3", 2.0, Logger::bench, 20), "1/f", "1/f", pink);
  const Score s = run_file(f, dir.path());
  print(s);
  ASSERT_TRUE(s.identifiable) << s.why_not_identifiable;
  EXPECT_TRUE(s.right_set) << s.found;
  EXPECT_LE(s.worst_error, 0.15) << s.params;
}

}  // namespace
