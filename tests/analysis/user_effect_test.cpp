// A user-written effect, exactly as analysis/README.md's worked example adds one: one class
// registered by name, and its YAML block. compare picks it up from the model file; diagnose
// picks it up as a candidate by itself (all its parameters have defaults meaning "absent").
#include <gtest/gtest.h>

#include "throat_deposit_effect.hpp"
#include "temp_file.hpp"
#include "workbench_test_util.hpp"

namespace {

namespace fs = std::filesystem;

TEST(UserEffect, CompareAndDiagnosePickItUp) {
  hil::test::TempDir dir;
  hil::test::Scenario s;
  s.name = "deposit";
  s.seed = 115;
  s.reference_yaml = hil::test::reference_square(1.0, 1.4, 3.0);
  s.truth = [](const hil::plant::Plant& p) { return hil::test::with_block(p, "throat_deposit", "blockage: 0.08"); };
  const fs::path data = hil::test::make_measurement(s, dir.path());

  // compare: a model file with the block.
  std::ifstream nominal(hil::test::nominal_model());
  std::string yaml((std::istreambuf_iterator<char>(nominal)), std::istreambuf_iterator<char>());
  yaml += "  throat_deposit:\n    blockage: 0.08\n";
  const auto model = dir.write("with_deposit.yaml", yaml);
  const auto c = hil::test::run_compare(model, data, dir.path() / "cmp");
  EXPECT_GE(c.at("fit_pct").get<double>(), c.at("noise_floor_fit_pct").get<double>() - 0.1);

  // diagnose: a candidate by itself, found and fitted.
  const auto d = hil::test::run_diagnose(hil::test::nominal_model(), data, dir.path() / "diag", dir.path() / "fitted.yaml");
  const std::string why = hil::test::brief(d);
  ASSERT_FALSE(d.at("ranking").empty());
  EXPECT_EQ(d.at("ranking")[0].at("effect"), "throat_deposit") << why;
  ASSERT_EQ(d.at("added").size(), 1u) << why;
  EXPECT_NEAR(hil::test::param(d.at("added")[0], "blockage"), 0.08, 0.012) << why;
  EXPECT_GE(d.at("fit_after_pct").get<double>(), d.at("noise_floor_fit_pct").get<double>() - 1.0) << why;
  // The written model carries it as a named block, and loads.
  const auto fitted = hil::plant::Plant::load(dir.path() / "fitted.yaml");
  ASSERT_NE(fitted.find("throat_deposit"), nullptr);
}

}  // namespace
