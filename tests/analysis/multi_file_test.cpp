// Several files of one rig at once: `diagnose --data a --data b --data c` fits one set of
// parameters to all of them. Three runs share a gap of 1.6 deg (nominal 1.0) and a 15 ms sensor
// lag; the logger records the command and the pressure, no encoder, so the drive's own lag sits
// between them too. In the slow run (10 deg/s) a sensor lag and a slower drive look alike: both
// hold the reading back by a time, and at one speed a time is an angle (lag x speed); with the gap
// in between, that run alone ends at its noise floor with a 58 ms drive lag and no sensor lag.
// The 20 and 40 deg/s runs alone find both (measured); diagnosed together, the three do. The test
// checks that premise on the slow run, then the joint diagnosis.
// A step of the gap is per file: it happened during one run (or between two), so the runs before
// it have the old gap and the runs after it the new one.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "temp_file.hpp"
#include "workbench_test_util.hpp"

namespace {

namespace fs = std::filesystem;
using hil::plant::Plant;
using hil::test::with_block;

constexpr double kGapDeg = 1.6, kLagS = 0.015;

Plant truth(const Plant& p) {
  return with_block(with_block(p, "backlash_change", "gap_deg: 1.6"), "sensor_lag", "time_constant_s: 0.015");
}

// True when diagnosis `d` found both effects, each within 15 %.
bool found_both(const nlohmann::json& d) {
  const double gap = hil::test::added_param(d, "backlash_change", "gap_deg");
  const double lag = hil::test::added_param(d, "sensor_lag", "time_constant_s");
  return std::abs(gap - kGapDeg) <= 0.15 * kGapDeg && std::abs(lag - kLagS) <= 0.15 * kLagS;
}

// Run i (0-based) of three of one rig: 16 s, 2 kPa noise, each file on its own clock 100 s apart.
hil::test::LabLog run_log(const std::string& prefix, int i, std::uint64_t seed0, bool encoder) {
  hil::test::LabLog log;
  log.name = prefix + std::to_string(i + 1);
  log.t0_s = 100.0 * (i + 1);
  log.duration_s = 16;
  log.seed = seed0 + static_cast<std::uint64_t>(i);
  log.noise_kpa = 2.0;
  log.encoder = encoder;
  return log;
}

TEST(MultiFile, ThreeRunsOfOneRigSeparateAGapAndASensorLagThatOneRunCannot) {
  hil::test::TempDir dir;
  const double speeds_deg_s[] = {10.0, 20.0, 40.0};
  std::vector<fs::path> files;
  bool slowest_alone_found_both = true;
  for (int i = 0; i < 3; ++i) {
    hil::test::LabLog log = run_log("run", i, 911, false);
    log.truth = truth;
    log.command_deg = hil::test::command_triangle(8.0, 13.0, speeds_deg_s[i], 0.0);
    files.push_back(hil::test::make_lab_log(log, dir.path()));
    const auto d = hil::test::run_diagnose(hil::test::nominal_model(), files.back(), dir.path() / ("diag" + std::to_string(i)));
    if (i == 0) slowest_alone_found_both = found_both(d);
    std::printf("[ one run, %g deg/s ] %s\n", speeds_deg_s[i], hil::test::brief(d).c_str());
  }
  // At 10 deg/s alone the sensor lag was traded for a drive lag (measured: 58 ms, with the gap, at
  // that file's noise floor) while the criterion counted N / tau of the residual; with the
  // prewhitened criterion (2026-12) the slow run alone finds both (gap 1.600 deg, lag 14.97 ms), so
  // this is no longer a premise of the test: what follows checks that three runs together still
  // find both, with the smaller uncertainty.
  std::printf("[ premise ] the 10 deg/s run alone %s both\n", slowest_alone_found_both ? "finds" : "does not find");

  const auto d = hil::test::run_diagnose(hil::test::nominal_model(), hil::analysis::DataFiles(files), dir.path() / "joint",
                                         dir.path() / "fitted.yaml");
  std::printf("[ three runs together ] %s\n", hil::test::brief(d).c_str());
  EXPECT_EQ(d.at("verdict"), "explained");
  EXPECT_TRUE(found_both(d));
  ASSERT_EQ(d.at("added").size(), 2u);
  for (const auto& a : d.at("added")) {
    if (a.at("effect") == "backlash_change") {
      EXPECT_EQ(a.at("variant"), "constant gap");
    }
  }
  EXPECT_GE(d.at("fit_after_pct").get<double>(), d.at("noise_floor_fit_pct").get<double>() - 1.0);
  ASSERT_EQ(d.at("files").size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    const auto& f = d.at("files")[i];
    EXPECT_EQ(f.at("data_file"), files[i].string());
    EXPECT_DOUBLE_EQ(f.at("time_origin_s").get<double>(), 100.0 * static_cast<double>(i + 1));
    // Each file on its own ends within a point of its own floor: no file carries the others' error.
    EXPECT_GE(f.at("fit_after_pct").get<double>(), f.at("noise_floor_fit_pct").get<double>() - 1.0) << f.dump();
  }
  std::string shared;
  for (const auto& p : d.at("shared_parameters")) shared += p.get<std::string>() + " ";
  EXPECT_NE(shared.find("backlash_change.gap_deg"), std::string::npos) << shared;
  EXPECT_NE(shared.find("sensor_lag.time_constant_s"), std::string::npos) << shared;
  std::string summary;
  for (const auto& line : d.at("summary")) summary += line.get<std::string>() + " ";
  EXPECT_NE(summary.find("shared by all of them"), std::string::npos) << summary;
  // The fitted model, compared with each file, is at that file's floor.
  for (std::size_t i = 0; i < 3; ++i) {
    const auto c = hil::test::run_compare(dir.path() / "fitted.yaml", files[i], dir.path() / ("cmp" + std::to_string(i)));
    EXPECT_GE(c.at("fit_pct").get<double>(), c.at("noise_floor_fit_pct").get<double>() - 1.0) << files[i];
  }
}

// The gap grows from the nominal 1.0 to 1.8 deg 6 s into the second of three runs (a tooth
// chipped): the first run has the old gap throughout, the third the new one. A step time shared by
// the three files (6 s into each) would misfit the first and the third; per file it is found in
// the second, and everything else is shared.
TEST(MultiFile, AGapThatSteppedDuringTheSecondRunIsFoundInThatRun) {
  constexpr double kStepAfterS = 6.0, kStepDeg = 0.8;
  hil::test::TempDir dir;
  std::vector<fs::path> files;
  for (int i = 0; i < 3; ++i) {
    hil::test::LabLog log = run_log("chipped", i, 931, true);
    // The truth's clock is the file's (it starts at t0_s).
    const std::string gap = i == 0 ? "gap_deg: 1.0"
                            : i == 1
                                ? "{gap_deg: 1.0, step_deg: 0.8, step_time_s: " + std::to_string(log.t0_s + kStepAfterS) + "}"
                                : "gap_deg: 1.8";
    log.truth = [gap](const Plant& p) { return with_block(p, "backlash_change", gap); };
    log.command_deg = hil::test::command_triangle(8.0, 13.0, 20.0, 0.0);
    files.push_back(hil::test::make_lab_log(log, dir.path()));
  }
  const auto d = hil::test::run_diagnose(hil::test::nominal_model(), hil::analysis::DataFiles(files), dir.path() / "joint",
                                         dir.path() / "fitted.yaml");
  const std::string why = hil::test::brief(d);
  std::printf("[ three runs, a step in the second ] %s\n", why.c_str());
  EXPECT_EQ(d.at("verdict"), "explained") << why;
  ASSERT_EQ(d.at("added").size(), 1u) << why;
  const auto& a = d.at("added")[0];
  EXPECT_EQ(a.at("effect"), "backlash_change");
  EXPECT_EQ(a.at("variant"), "gap step") << why;
  EXPECT_NEAR(hil::test::param(a, "gap_deg"), 1.0, 0.15);
  EXPECT_NEAR(hil::test::param(a, "step_deg"), kStepDeg, 0.15 * kStepDeg);
  // The step time: in the second file, within a quarter of a cycle (the step only shows at the
  // next reversal, every 0.25 s at 20 deg/s over 5 deg).
  ASSERT_EQ(d.at("per_file_parameters").size(), 1u) << d.at("per_file_parameters").dump();
  const auto& pf = d.at("per_file_parameters")[0];
  EXPECT_EQ(pf.at("parameter"), "backlash_change.step_time_s");
  EXPECT_EQ(pf.at("file_index"), 1);
  EXPECT_EQ(pf.at("data_file"), files[1].string());
  EXPECT_NEAR(pf.at("value").get<double>(), kStepAfterS, 0.3);
  EXPECT_NEAR(pf.at("file_time_s").get<double>(), 200.0 + kStepAfterS, 0.3);
  for (const auto& p : a.at("parameters")) {
    if (p.at("key") == "step_time_s") {
      EXPECT_EQ(p.at("file_index"), 1);
    }
  }
  std::string shared;
  for (const auto& p : d.at("shared_parameters")) shared += p.get<std::string>() + " ";
  EXPECT_NE(shared.find("backlash_change.step_deg"), std::string::npos) << shared;
  EXPECT_EQ(shared.find("step_time_s"), std::string::npos) << shared;
  std::string summary;
  for (const auto& line : d.at("summary")) summary += line.get<std::string>() + " ";
  EXPECT_NE(summary.find("per file"), std::string::npos) << summary;
  for (std::size_t i = 0; i < 3; ++i) {
    const auto& f = d.at("files")[i];
    EXPECT_GE(f.at("fit_after_pct").get<double>(), f.at("noise_floor_fit_pct").get<double>() - 1.0) << f.dump();
  }
  // The written model is the rig as the last run saw it: the wider gap from its first row.
  const auto last = hil::test::run_compare(dir.path() / "fitted.yaml", files[2], dir.path() / "cmp_last");
  EXPECT_GE(last.at("fit_pct").get<double>(), last.at("noise_floor_fit_pct").get<double>() - 1.0);
}

}  // namespace
