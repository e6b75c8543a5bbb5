// The telemetry schema: the measurement format of physics.md section 4 first, every name unique
// and carrying its unit, the truth-only columns the ones a real rig cannot know.
#include "hil/telemetry_schema.hpp"

#include <gtest/gtest.h>

#include <set>
#include <string>

namespace {

using hil::telemetry::Col;
using hil::telemetry::kColumns;

TEST(TelemetrySchema, StartsWithTheMeasurementFormatOfPhysicsSection4) {
  const char* section4[] = {"t_s", "theta_cmd_deg", "p_meas_mpa", "theta_motor_deg", "p_ref_mpa"};
  for (std::size_t i = 0; i < 5; ++i) EXPECT_EQ(kColumns[i].name, section4[i]);
  EXPECT_EQ(hil::telemetry::kSimColumns, 12u);
  EXPECT_EQ(hil::telemetry::name(Col::p_chamber_mpa), kColumns[hil::telemetry::kSimColumns - 1].name);
  EXPECT_EQ(hil::telemetry::name(Col::loop_flags), kColumns.back().name);
}

TEST(TelemetrySchema, NamesAreUniqueAndCarryTheirUnit) {
  std::set<std::string> seen;
  const std::set<std::string> unitless = {"touch_state", "motion_intention", "loop_flags"};
  for (const auto& c : kColumns) {
    const std::string n(c.name);
    EXPECT_TRUE(seen.insert(n).second) << n;
    const bool unit = n.ends_with("_s") || n.ends_with("_deg") || n.ends_with("_mpa") || n.ends_with("_us");
    EXPECT_TRUE(unit || unitless.count(n)) << n;
    EXPECT_FALSE(c.meaning.empty()) << n;
    if (unitless.count(n)) {
      EXPECT_EQ(c.decimals, 0) << n << " holds integers";
    }
  }
}

TEST(TelemetrySchema, OnlyTheSimulatedPlantsInternalsAreTruthOnly) {
  std::set<std::string> truth;
  for (const auto& c : kColumns) {
    if (c.truth_only) truth.insert(std::string(c.name));
  }
  EXPECT_EQ(truth, (std::set<std::string>{"theta_valve_deg", "gap_true_deg", "p_chamber_mpa"}));
}

}  // namespace
