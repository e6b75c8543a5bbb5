// What CampaignRunner refuses before anything runs or reaches the loop: a pace that would leave
// the loop deaf to an abort, and an injection whose value is not a number the record can hold.
// Both reached the loop before: `speed: 1e-9` ran a period for 11 days (abort answered 202, the
// run stayed "running", SIGTERM no longer stopped the server), `speed: 1e-300` overflowed the
// period's float-to-integer conversion (undefined behaviour), and a bias or noise of 1e308 kPa
// wrote 'nan' into telemetry.csv.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "hil/bench/server/runner.hpp"
#include "hil/units.hpp"
#include "loop_fixture.hpp"

namespace {

using namespace hil::bench;
using hil::test::TempDir;

std::string refused_field(CampaignRunner& runner, double speed, const Campaign& c) {
  StartRequest r;
  r.campaign = c;
  r.rig = load_rig_config(hil::test::source_path("configs/rigs/sim.yaml"));
  r.speed = speed;
  try {
    runner.start(std::move(r));
  } catch (const BadField& e) {
    EXPECT_NE(std::string(e.what()).find("speed"), std::string::npos) << e.what();
    return e.field;
  }
  runner.abort("test");
  runner.wait();
  return "(started)";
}

TEST(RunnerLimits, ASpeedThatLeavesTheLoopDeafIsRefusedNamingTheField) {
  TempDir dir;
  RunnerOptions o;
  o.runs_dir = dir.path() / "runs";
  CampaignRunner runner(o);
  const Campaign c = hil::test::short_campaign(1.0);  // 1 ms period
  for (const double speed : {1e-9, 1e-300, 0.0, -1.0, 0.005, 101.0, std::numeric_limits<double>::quiet_NaN(),
                             std::numeric_limits<double>::infinity()}) {
    EXPECT_EQ(refused_field(runner, speed, c), "speed") << speed;
  }
  EXPECT_FALSE(runner.running());
  // A 1 s control period at half speed would be a 2 s wall period: refused, and the error says
  // which speed would do.
  Campaign slow = c;
  slow.period_s = 1.0;
  EXPECT_EQ(refused_field(runner, 0.5, slow), "speed");
  const std::string why = speed_problem(0.5, 1.0);
  EXPECT_NE(why.find("at least 1"), std::string::npos) << why;
  // The edges are accepted.
  EXPECT_EQ(speed_problem(kMinSpeed, 1e-3), "");
  EXPECT_EQ(speed_problem(kMaxSpeed, 1e-3), "");
  EXPECT_EQ(speed_problem(1.0, 1.0), "");
}

TEST(RunnerLimits, AnInjectionOutsideItsRangeIsRefusedNamingTheField) {
  using K = LoopRequest::Kind;
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  struct Case {
    LoopRequest r;
    const char* field;
  };
  const Case bad[] = {
      {{.kind = K::sensor_fault, .sensor = SensorFault::bias, .value = 1e308 * hil::units::kPaPerKpa}, "bias_kpa"},
      {{.kind = K::sensor_fault, .sensor = SensorFault::bias, .value = -2e7}, "bias_kpa"},
      {{.kind = K::sensor_fault, .sensor = SensorFault::bias, .value = nan}, "bias_kpa"},
      {{.kind = K::sensor_fault, .sensor = SensorFault::noise, .value = 1e308}, "rms_kpa"},
      {{.kind = K::sensor_fault, .sensor = SensorFault::noise, .value = -1}, "rms_kpa"},
      {{.kind = K::sensor_fault, .sensor = SensorFault::noise, .value = inf}, "rms_kpa"},
      {{.kind = K::sensor_fault, .sensor = SensorFault::stuck, .duration_s = nan}, "duration_s"},
      {{.kind = K::drive_fault, .duration_s = 1e9}, "duration_s"},
      {{.kind = K::set_gap, .value = hil::units::deg_to_rad(11)}, "gap_deg"},
      {{.kind = K::set_gap, .value = nan}, "gap_deg"},
  };
  for (const Case& c : bad) {
    try {
      check_injection(c.r);
      ADD_FAILURE() << c.field << ": accepted";
    } catch (const BadField& e) {
      EXPECT_EQ(e.field, c.field) << e.what();
    }
  }
  const LoopRequest good[] = {
      {.kind = K::sensor_fault, .sensor = SensorFault::bias, .value = -kMaxSensorBiasKpa * hil::units::kPaPerKpa},
      {.kind = K::sensor_fault, .sensor = SensorFault::noise, .value = 50e3, .duration_s = kMaxInjectionS},
      {.kind = K::set_gap, .value = hil::units::deg_to_rad(2.5)},
      {.kind = K::clear_faults},
  };
  for (const LoopRequest& r : good) EXPECT_NO_THROW(check_injection(r));
}

}  // namespace
