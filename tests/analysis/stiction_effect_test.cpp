// A user effect at a stage the model already fills (issue 37 point 5a): a valve that sticks,
// written as a user would, in this one file, at the transmission stage, after the backlash. Before,
// diagnose skipped every user effect at the motor, transmission, throat and chamber stages (the
// plant took exactly one effect there), so a stiction would never have been tried.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>

#include "hil/plant/registry.hpp"
#include "hil/units.hpp"
#include "temp_file.hpp"
#include "workbench_test_util.hpp"

namespace hil::plant {

// Stick-slip: the valve holds where it stopped until the transmission has wound up by
// breakaway_deg against it (static friction), then slips to where the backlash would put it.
// breakaway_deg = 0 (the default) is no stiction: the effect is absent, so diagnose tries it.
class TestValveStiction final : public ScalarEffect<TestValveStiction> {
 public:
  static constexpr std::string_view kKind = "test_valve_stiction";
  static constexpr Stage kStage = Stage::transmission;
  static constexpr ParamSpec kSpecs[] = {
      {"breakaway_deg", 0, 5, false, false, 0.0, "wind-up of the transmission at which the stuck valve slips"},
  };
  using ScalarEffect::ScalarEffect;
  std::size_t state_size() const noexcept override { return 1; }
  void settle(std::span<double> x, Signals& s) const override { x[0] = s.theta_valve_rad; }
  void step(std::span<double> x, Signals& s, double, Rng&) const noexcept override {
    if (std::abs(s.theta_valve_rad - x[0]) > units::deg_to_rad(value(0))) x[0] = s.theta_valve_rad;
    s.theta_valve_rad = s.theta_throat_rad = x[0];
  }
};

HIL_REGISTER_EFFECT(TestValveStiction, "test only: a valve that sticks until the transmission winds up (stick-slip)")

}  // namespace hil::plant

namespace {

TEST(UserEffectAtAnyStage, AStictionAtTheTransmissionStageIsFound) {
  constexpr double kBreakaway_deg = 0.4;
  hil::test::TempDir dir;
  hil::test::Scenario s;
  s.name = "stiction";
  s.seed = 3701;
  s.encoder = true;
  s.compensation = "constant";
  s.reference_yaml = hil::test::reference_random(3702, 0.9, 1.5, 1.0, 3.0);
  s.truth = [&](const hil::plant::Plant& p) {
    return hil::test::with_block(p, "test_valve_stiction", "breakaway_deg: " + std::to_string(kBreakaway_deg));
  };
  const auto data = hil::test::make_measurement(s, dir.path());
  const auto d = hil::test::run_diagnose(hil::test::nominal_model(), data, dir.path() / "diag", dir.path() / "fitted.yaml");
  const std::string why = hil::test::brief(d);
  ASSERT_EQ(d.at("added").size(), 1u) << why;
  EXPECT_EQ(d.at("added")[0].at("effect"), "test_valve_stiction") << why;
  const double found = hil::test::param(d.at("added")[0], "breakaway_deg");
  EXPECT_NEAR(found, kBreakaway_deg, 0.15 * kBreakaway_deg) << why;
  // The truth itself, replayed: a stuck valve's place depends on its whole history, so the replay
  // (driven by the logged encoder) does not reach the noise floor even with the true breakaway.
  // The diagnosis must fit as well as the truth does.
  std::ifstream nominal(hil::test::nominal_model());
  std::string yaml((std::istreambuf_iterator<char>(nominal)), std::istreambuf_iterator<char>());
  yaml += "  test_valve_stiction:\n    breakaway_deg: " + std::to_string(kBreakaway_deg) + "\n";
  const auto truth = hil::test::run_compare(dir.write("truth.yaml", yaml), data, dir.path() / "truth");
  EXPECT_GE(d.at("fit_after_pct").get<double>(), truth.at("fit_pct").get<double>() - 0.1) << why;
  std::printf("[ stiction ] the truth replayed: fit %.2f %%\n", truth.at("fit_pct").get<double>());
  // The written model holds both transmission effects, the stiction after the backlash, and loads.
  const auto fitted = hil::plant::Plant::load(dir.path() / "fitted.yaml");
  ASSERT_NE(fitted.find("test_valve_stiction"), nullptr);
  ASSERT_NE(fitted.find("backlash"), nullptr);
  std::printf("[ stiction ] breakaway %.4g deg (truth %.4g), fit %.2f -> %.2f %% (floor %.2f %%), %s\n", found, kBreakaway_deg,
              d.at("fit_before_pct").get<double>(), d.at("fit_after_pct").get<double>(),
              d.at("noise_floor_fit_pct").get<double>(), d.at("verdict").get<std::string>().c_str());
}

}  // namespace
