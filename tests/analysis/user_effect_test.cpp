// A user-written effect, exactly as analysis/README.md's worked example adds one: one class
// registered by name, and its YAML block. compare picks it up from the model file; diagnose
// picks it up as a candidate by itself (all its parameters have defaults meaning "absent").
#include <gtest/gtest.h>

#include "hil/plant/registry.hpp"
#include "temp_file.hpp"
#include "workbench_test_util.hpp"

namespace hil::plant {

// Slag deposits narrow the throat: the area is (1 - blockage) times what the valve angle gives.
class ThroatDeposit final : public ScalarEffect<ThroatDeposit> {
 public:
  static constexpr std::string_view kKind = "throat_deposit";
  static constexpr Stage kStage = Stage::throat_modifier;
  static constexpr ParamSpec kSpecs[] = {
      {"blockage", 0, 0.9, false, false, 0.0, "fraction of the throat area blocked by deposits"},
  };
  using ScalarEffect::ScalarEffect;
  void settle(std::span<double>, Signals& s) const override { apply(s); }
  void step(std::span<double>, Signals& s, double, Rng&) const noexcept override { apply(s); }

 private:
  void apply(Signals& s) const noexcept { s.throat_area_m2 *= 1.0 - value(0); }
};

HIL_REGISTER_EFFECT(ThroatDeposit, "slag deposits narrow the throat by a fixed fraction")

}  // namespace hil::plant

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
