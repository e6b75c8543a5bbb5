// A gap that drifts and steps in one run (issue 37 point 4): the step form alone absorbs the
// drift into a larger step, and no form held both. backlash_change's "drift and step" form is
// tried only in place of an accepted simpler form, and kept when its extra parameters earn their
// place against it by the criterion: here every parameter is found within 15 %. (A temporary
// throat blockage, which the form explained when it was a first choice, stays unexplained:
// MultiEffect.ATemporaryBlockageIsNotExplainedAndItsSpanIsNamed in test_analysis_multi.)
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "temp_file.hpp"
#include "workbench_test_util.hpp"

namespace {

using hil::plant::Plant;

const nlohmann::json* added_gap(const nlohmann::json& d) {
  for (const auto& a : d.at("added"))
    if (a.at("effect") == "backlash_change") return &a;
  return nullptr;
}

TEST(GapForms, ADriftAndAStepTogetherAreBothFound) {
  constexpr double kGap_deg = 1.0, kDrift_deg_per_s = 0.01, kStep_deg = 0.4, kStepTime_s = 21.0;
  hil::test::TempDir dir;
  hil::test::Scenario s;
  s.name = "drift_step";
  s.seed = 3741;
  s.duration_s = 40;
  s.encoder = true;
  s.compensation = "none";
  s.reference_yaml = hil::test::reference_random(3742, 0.9, 1.5, 1.0, 2.5);
  s.truth = [&](const Plant& p) {
    return hil::test::with_block(
        p, "backlash_change",
        "{gap_deg: " + std::to_string(kGap_deg) + ", drift_deg_per_s: " + std::to_string(kDrift_deg_per_s) +
            ", step_deg: " + std::to_string(kStep_deg) + ", step_time_s: " + std::to_string(kStepTime_s) + "}");
  };
  const auto d =
      hil::test::run_diagnose(hil::test::nominal_model(), hil::test::make_measurement(s, dir.path()), dir.path() / "diag");
  const std::string why = hil::test::brief(d) + " revisions " + d.at("revisions").dump();
  const nlohmann::json* gap = added_gap(d);
  ASSERT_NE(gap, nullptr) << why;
  EXPECT_EQ(gap->at("variant"), "drift and step") << why;
  EXPECT_EQ(d.at("added").size(), 1u) << why;
  const double g = hil::test::param(*gap, "gap_deg"), r = hil::test::param(*gap, "drift_deg_per_s");
  const double st = hil::test::param(*gap, "step_deg"), t = hil::test::param(*gap, "step_time_s");
  EXPECT_NEAR(g, kGap_deg, 0.15 * kGap_deg) << why;
  EXPECT_NEAR(r, kDrift_deg_per_s, 0.15 * kDrift_deg_per_s) << why;
  EXPECT_NEAR(st, kStep_deg, 0.15 * kStep_deg) << why;
  // A step is located by the motions around it: within a second of the truth.
  EXPECT_NEAR(t, kStepTime_s, 1.0) << why;
  EXPECT_EQ(d.at("verdict"), "explained") << why;
  std::printf("[ drift and step ] gap %.4g deg, drift %.4g deg/s, step %.4g deg at %.4g s; fit %.2f %% (floor %.2f %%)\n", g, r,
              st, t, d.at("after").at("fit_pct").get<double>(), d.at("noise_floor_fit_pct").get<double>());
}

}  // namespace
