// A user effect that declares how to find it (issue 37 point 5b): analysis/README.md's worked
// example, a gear's transmission error with its fit prior in the one file gear_ripple_effect.cpp
// (the pitch searched on a grid over 4-8 deg, the amplitude by LM from a few sizes). On a file made
// with a 0.2 deg ripple of a 5.5 deg pitch, diagnose adds it with the pitch searched, both within
// 15 % (the pitch within 2 %), and writes it into the model.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "hil/analysis/candidates.hpp"
#include "hil/analysis/replay.hpp"
#include "hil/plant/plant.hpp"
#include "temp_file.hpp"
#include "workbench_test_util.hpp"

namespace {

using hil::plant::Plant;

TEST(UserFitPrior, TheDeclaredPriorBecomesTheCandidate) {
  const Plant nominal = hil::analysis::noise_free(Plant::load(hil::test::nominal_model()));
  const auto c = hil::analysis::candidates_for(nominal, {"gear_ripple"});
  ASSERT_EQ(c.size(), 1u);
  ASSERT_EQ(c[0].variants.size(), 2u);
  EXPECT_EQ(c[0].variants[0].name, "drawing's pitch");
  ASSERT_EQ(c[0].variants[0].params.size(), 1u);  // the pitch held at the drawing's
  EXPECT_EQ(c[0].variants[0].params[0].key, "amplitude_deg");
  ASSERT_EQ(c[0].variants[1].params.size(), 2u);
  const auto& pitch = c[0].variants[1].params[1];
  EXPECT_TRUE(pitch.grid);
  hil::analysis::ReplayData none;
  const auto grid = pitch.grid_values(none);
  ASSERT_EQ(grid.size(), 401u);
  EXPECT_DOUBLE_EQ(grid.front(), 4.0);
  EXPECT_DOUBLE_EQ(grid.back(), 8.0);
  // The built-ins come first, in their order, each from its effect's own prior.
  const auto all = hil::analysis::candidates_for(nominal);
  const auto builtin = hil::analysis::builtin_candidate_names();
  ASSERT_GT(all.size(), builtin.size());
  for (std::size_t i = 0; i < builtin.size(); ++i) EXPECT_EQ(all[i].name, builtin[i]);
}

TEST(UserFitPrior, DiagnoseFindsTheGearRippleWithItsPitch) {
  constexpr double kAmplitude_deg = 0.2, kPitch_deg = 5.5;
  hil::test::TempDir dir;
  hil::test::Scenario s;
  s.name = "gear_ripple_prior";
  s.seed = 3711;
  s.encoder = true;
  s.compensation = "constant";
  s.reference_yaml = hil::test::reference_random(3712, 0.8, 1.6, 1.0, 3.0);
  s.truth = [&](const Plant& p) {
    return hil::test::with_block(
        p, "gear_ripple",
        "{amplitude_deg: " + std::to_string(kAmplitude_deg) + ", pitch_deg: " + std::to_string(kPitch_deg) + "}");
  };
  const auto data = hil::test::make_measurement(s, dir.path());
  const auto d = hil::test::run_diagnose(hil::test::nominal_model(), data, dir.path() / "diag", dir.path() / "fitted.yaml");
  const std::string why = hil::test::brief(d);
  ASSERT_EQ(d.at("added").size(), 1u) << why;
  const auto& added = d.at("added")[0];
  EXPECT_EQ(added.at("effect"), "gear_ripple") << why;
  EXPECT_EQ(added.at("variant"), "pitch searched") << why;
  const double amplitude = hil::test::param(added, "amplitude_deg"), pitch = hil::test::param(added, "pitch_deg");
  EXPECT_NEAR(amplitude, kAmplitude_deg, 0.15 * kAmplitude_deg) << why;
  EXPECT_NEAR(pitch, kPitch_deg, 0.02 * kPitch_deg) << why;
  EXPECT_GE(d.at("fit_after_pct").get<double>(), d.at("noise_floor_fit_pct").get<double>() - 0.5) << why;
  const auto fitted = Plant::load(dir.path() / "fitted.yaml");
  ASSERT_NE(fitted.find("gear_ripple"), nullptr);
  std::printf(
      "[ gear prior ] amplitude %.4g deg (truth %.4g), pitch %.4g deg (truth %.4g), fit %.2f -> %.2f %% (floor %.2f %%), %s\n",
      amplitude, kAmplitude_deg, pitch, kPitch_deg, d.at("fit_before_pct").get<double>(), d.at("fit_after_pct").get<double>(),
      d.at("noise_floor_fit_pct").get<double>(), d.at("verdict").get<std::string>().c_str());
}

}  // namespace
