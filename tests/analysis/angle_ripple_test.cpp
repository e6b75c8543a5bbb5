// Pointing at the effect nobody has written (issue 37 point 4): when nothing in the candidate list
// explains the residual, the signature says what kind of effect is missing. A gear's transmission
// error (out_of_list_effect.cpp: a 0.2 deg ripple with a 2 deg tooth pitch in the motor angle)
// leaves a residual periodic in the drive angle: compare's signature names the period, diagnose
// says `explained: false` and names it too, and the report has the residual against the angle.
// Other side: a slow misfit against the angle (a valve offset, smooth in the angle) and a healthy
// file name no period. The period is read within 8 % (measured: 2.10 deg for 2: the chamber's lag
// shifts the ripple one way while opening and the other while closing).
#include <gtest/gtest.h>

#include <cstdio>
#include <regex>
#include <string>

#include "temp_file.hpp"
#include "workbench_test_util.hpp"

namespace {

using hil::plant::Plant;
using hil::test::Scenario;
using hil::test::with_block;
namespace fs = std::filesystem;

constexpr double kPitch_deg = 2.0;  // the drive covers about 9 deg on this reference: 4.5 teeth

// The period the signature names in "... with a P deg period ...", or 0 when it names none.
double named_period_deg(const nlohmann::json& signature) {
  static const std::regex re("ripple of [0-9.e+-]+ kPa with a ([0-9.e+-]+) deg period");
  for (const auto& line : signature) {
    std::smatch m;
    const std::string s = line.get<std::string>();
    if (std::regex_search(s, m, re)) return std::stod(m[1].str());
  }
  return 0;
}

Scenario ripple_scenario() {
  Scenario s;
  s.name = "gear_ripple";
  s.seed = 3704;
  s.encoder = true;
  s.compensation = "constant";
  s.reference_yaml = hil::test::reference_random(3705, 0.8, 1.6, 1.0, 3.0);
  s.truth = [](const Plant& p) {
    return with_block(p, "test_gear_ripple", "{amplitude_deg: 0.2, pitch_deg: " + std::to_string(kPitch_deg) + "}");
  };
  return s;
}

TEST(AngleSignature, CompareNamesTheGearPeriodAndNotAPeriodWhereThereIsNone) {
  hil::test::TempDir dir;
  const fs::path ripple = hil::test::make_measurement(ripple_scenario(), dir.path());
  const auto c = hil::test::run_compare(hil::test::nominal_model(), ripple, dir.path() / "cmp_ripple");
  const double period = named_period_deg(c.at("signature"));
  std::printf("[ ripple ] named period %.4g deg (truth %.4g), json %s\n", period, kPitch_deg,
              c.at("diagnostics").at("angle_ripple").dump().c_str());
  EXPECT_NEAR(period, kPitch_deg, 0.08 * kPitch_deg) << c.at("signature").dump(1);
  EXPECT_NEAR(c.at("diagnostics").at("angle_ripple").at("period_deg").get<double>(), period, 0.01);
  EXPECT_GE(c.at("diagnostics").at("vs_drive_angle").at("x").size(), 20u);

  // A valve offset: the residual changes with the angle, smoothly; and nothing missing at all.
  Scenario offset = ripple_scenario();
  offset.name = "offset_only";
  offset.truth = [](const Plant& p) { return with_block(p, "valve_offset", "offset_deg: 0.8"); };
  Scenario healthy = ripple_scenario();
  healthy.name = "healthy";
  healthy.truth = [](const Plant& p) { return p; };
  for (const Scenario& s : {offset, healthy}) {
    const auto r = hil::test::run_compare(hil::test::nominal_model(), hil::test::make_measurement(s, dir.path()),
                                          dir.path() / ("cmp_" + s.name));
    EXPECT_EQ(named_period_deg(r.at("signature")), 0.0) << s.name << ": " << r.at("signature").dump(1);
  }
}

TEST(AngleSignature, DiagnoseCallsTheGearRippleUnexplainedAndNamesItsPeriod) {
  hil::test::TempDir dir;
  const fs::path ripple = hil::test::make_measurement(ripple_scenario(), dir.path());
  const auto d = hil::test::run_diagnose(hil::test::nominal_model(), ripple, dir.path() / "diag");
  EXPECT_FALSE(d.at("explained").get<bool>()) << hil::test::brief(d);
  const double period = named_period_deg(d.at("signature"));
  EXPECT_NEAR(period, kPitch_deg, 0.08 * kPitch_deg) << d.at("signature").dump(1);
  std::printf("[ ripple ] diagnose: %s, named period %.4g deg\n", d.at("verdict").get<std::string>().c_str(), period);
}

}  // namespace
