// Two effects that pressure alone cannot tell apart: a c* efficiency below one discharges less gas
// at the same pressure, exactly as a throat narrowed by the same fraction does (mdot_out =
// Pg At / c*). Both are registered here as user effects, so diagnose has both as candidates; a file
// with a 6 % deposit is explained by one of them, and the other must be reported as a rival (a
// whole-model BIC within the criterion's margin), not silently passed over. Its own program: the
// twin candidates would change what other tests' diagnoses rank first.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "hil/plant/registry.hpp"
#include "throat_deposit_effect.hpp"
#include "temp_file.hpp"
#include "workbench_test_util.hpp"

namespace hil::plant {

// Combustion below its c*: the chamber discharges (1 - loss) of what the nominal c* gives, which
// enters the chamber equation as the effective throat area (1 - loss) At: in the data, the throat
// deposit's twin (throat_deposit_effect.hpp).
class CstarLoss final : public ScalarEffect<CstarLoss> {
 public:
  static constexpr std::string_view kKind = "cstar_loss";
  static constexpr Stage kStage = Stage::throat_modifier;
  static constexpr ParamSpec kSpecs[] = {
      {"loss", 0, 0.5, false, false, 0.0, "fraction of the discharge lost to a c* efficiency below one"},
  };
  using ScalarEffect::ScalarEffect;
  void settle(std::span<double>, Signals& s) const override { apply(s); }
  void step(std::span<double>, Signals& s, double, Rng&) const noexcept override { apply(s); }

 private:
  void apply(Signals& s) const noexcept { s.throat_area_m2 *= 1.0 - value(0); }
};
HIL_REGISTER_EFFECT(CstarLoss, "combustion efficiency: the discharge at the nominal c* scaled down")

}  // namespace hil::plant

namespace {

TEST(RivalEffect, AnEffectTheFileCannotTellFromTheOneFoundIsReportedAsARival) {
  hil::test::TempDir dir;
  hil::test::Scenario s;
  s.name = "deposit_or_cstar";
  s.seed = 121;
  s.reference_yaml = hil::test::reference_square(1.0, 1.4, 3.0);
  s.truth = [](const hil::plant::Plant& p) { return hil::test::with_block(p, "throat_deposit", "blockage: 0.06"); };
  const auto data = hil::test::make_measurement(s, dir.path());
  const auto d = hil::test::run_diagnose(hil::test::nominal_model(), data, dir.path() / "diag");
  const std::string why = hil::test::brief(d);
  ASSERT_EQ(d.at("added").size(), 1u) << why;
  const std::string found = d.at("added")[0].at("effect");
  ASSERT_TRUE(found == "throat_deposit" || found == "cstar_loss") << why;
  const std::string other = found == "throat_deposit" ? "cstar_loss" : "throat_deposit";
  EXPECT_EQ(d.at("verdict"), "explained") << why;
  const auto& rivals = d.at("rivals");
  const auto twin =
      std::find_if(rivals.begin(), rivals.end(), [&](const nlohmann::json& r) { return r.at("alternative") == other; });
  ASSERT_NE(twin, rivals.end()) << rivals.dump(2) << "\n" << why;
  EXPECT_EQ(twin->at("effect"), found);
  EXPECT_LT(std::abs(twin->at("delta_bic").get<double>()), 1.0) << twin->dump();  // the same model, another name
  EXPECT_NEAR(twin->at("fit_pct").get<double>(), d.at("fit_after_pct").get<double>(), 0.01) << twin->dump();
  std::string summary;
  for (const auto& line : d.at("summary")) summary += line.get<std::string>() + "\n";
  EXPECT_NE(summary.find("Not told apart on this file: " + other), std::string::npos) << summary;
  EXPECT_NE(summary.find("in place of " + found), std::string::npos) << summary;
}

}  // namespace
