// Each effect alone against its defining equation.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "hil/config.hpp"
#include "hil/plant/plant.hpp"
#include "hil/plant/registry.hpp"
#include "hil/units.hpp"
#include "temp_file.hpp"

using namespace hil::plant;
using hil::units::deg_to_rad;
using hil::units::rad_to_deg;

namespace {

Plant nominal() { return Plant::load(hil::test::source_path("configs/plant/nominal.yaml")); }
Plant quiet(const Plant& p) { return p.with(p.find("pressure_sensor")->with_params(std::vector<double>{0.0})); }

std::shared_ptr<const Effect> make(const std::string& kind, const std::string& yaml_block) {
  const auto node = hil::cfg::Node::load_string(yaml_block, kind + ".yaml");
  return find_effect(kind)->from_yaml(node);
}

TEST(Effects, MotorServoFollowsLagForSmallStepsAndRateLimitForLarge) {
  const Plant plant = quiet(nominal());
  PlantState st = plant.make_state(1);
  plant.settle(st, 1.0e6);
  const double m0 = st.s.theta_motor_rad;
  // Small step: first order, 63 % after tau = 10 ms (rate stays below 60 deg/s).
  const double small = deg_to_rad(0.2);
  for (int k = 0; k < 100; ++k) plant.step(st, {m0 + small, kNaN, kNaN}, 1e-4);  // 10 ms
  EXPECT_NEAR((st.s.theta_motor_rad - m0) / small, 1 - std::exp(-1.0), 1e-6);
  // Large step: slews at exactly 60 deg/s.
  plant.settle(st, 1.0e6);
  for (int k = 0; k < 100; ++k) plant.step(st, {m0 + deg_to_rad(20), kNaN, kNaN}, 1e-3);
  EXPECT_NEAR(rad_to_deg(st.s.theta_motor_rad - m0), 6.0, 1e-9);
}

TEST(Effects, TransportDelayShiftsTheCommand) {
  const Plant base = quiet(nominal());
  const Plant delayed = base.with(make("transport_delay", "delay_s: 0.0375\n"));
  PlantState a = base.make_state(1), b = delayed.make_state(1);
  base.settle(a, 1.0e6);
  delayed.settle(b, 1.0e6);
  const double c0 = a.s.theta_cmd_rad;
  std::vector<double> ma, mb;
  for (int k = 0; k < 400; ++k) {
    const double cmd = c0 + deg_to_rad(k >= 50 ? 0.2 : 0.0);  // small: the servo stays linear
    base.step(a, {cmd, kNaN, kNaN}, 1e-3);
    delayed.step(b, {cmd, kNaN, kNaN}, 1e-3);
    ma.push_back(a.s.theta_motor_rad);
    mb.push_back(b.s.theta_motor_rad);
  }
  // With a 37.5 ms delay the motor of b at k+37 and k+38 brackets a's at k (interpolated).
  for (int k = 60; k < 300; k += 10) {
    EXPECT_NEAR(mb[k + 38], 0.5 * (ma[k] + ma[k + 1]), 1e-12) << k;
  }
  EXPECT_DOUBLE_EQ(mb[80], c0);  // nothing moved before 50 + 37.5 ms
}

TEST(Effects, SensorLagIsFirstOrder) {
  const Plant base = quiet(nominal());
  const Plant lagged = base.with(make("sensor_lag", "time_constant_s: 0.05\n"));
  PlantState st = lagged.make_state(1);
  lagged.settle(st, 1.0e6);
  EXPECT_NEAR(st.s.p_meas_pa, 1.0e6, 1.0);  // settles to the same reading
  // Reading follows the chamber with dp_meas/dt = (p - p_meas)/tau.
  const double m = st.s.theta_motor_rad + deg_to_rad(2);
  double p_prev = st.s.p_meas_pa;
  for (int k = 0; k < 200; ++k) {
    lagged.step(st, {m, m, kNaN}, 1e-4);
    const double expected = st.s.p_chamber_pa + (p_prev - st.s.p_chamber_pa) * std::exp(-1e-4 / 0.05);
    EXPECT_NEAR(st.s.p_meas_pa, expected, 100.0);  // chamber moves within the step
    p_prev = st.s.p_meas_pa;
  }
}

TEST(Effects, SensorBiasOffsetAndGain) {
  const Plant plant = quiet(nominal()).with(make("sensor_bias", "offset_kpa: 20\ngain: 1.05\n"));
  PlantState st = plant.make_state(1);
  plant.settle(st, 1.2e6);  // the reading is 1.2 MPa
  EXPECT_NEAR(st.s.p_meas_pa, 1.2e6, 1.0);
  EXPECT_NEAR(st.s.p_chamber_pa, (1.2e6 - 20e3) / 1.05, 1.0);
}

TEST(Effects, ValveOffsetShiftsTheThroatAngle) {
  const Plant base = quiet(nominal());
  const Plant shifted = base.with(make("valve_offset", "offset_deg: 1.5\n"));
  PlantState a = base.make_state(1), b = shifted.make_state(1);
  base.settle(a, 1.0e6);
  shifted.settle(b, 1.0e6);
  EXPECT_NEAR(rad_to_deg(a.s.theta_valve_rad - b.s.theta_valve_rad), 1.5, 1e-6);
  EXPECT_NEAR(a.s.throat_area_m2, b.s.throat_area_m2, 1e-12);
}

TEST(Effects, ThroatErosionGrowsAreaLinearly) {
  const Plant base = quiet(nominal());
  const Plant eroding = base.with(make("throat_erosion", "rate_mm2_per_s: 0.5\n"));
  PlantState st = eroding.make_state(1);
  eroding.settle(st, 1.0e6);
  const double a0 = st.s.throat_area_m2, m = st.s.theta_motor_rad;
  for (int k = 0; k < 10000; ++k) eroding.step(st, {m, m, kNaN}, 1e-3);
  EXPECT_NEAR((st.s.throat_area_m2 - a0) * 1e6, 5.0, 1e-6);  // 0.5 mm^2/s for 10 s
  EXPECT_LT(st.s.p_chamber_pa, 0.95e6);                      // a bigger throat, a lower pressure
}

TEST(Effects, BacklashChangeStepAndDrift) {
  const Plant plant =
      quiet(nominal()).with(make("backlash_change", "gap_deg: 1.2\nstep_time_s: 1.9995\nstep_deg: 0.5\ndrift_deg_per_s: 0.01\n"));
  PlantState st = plant.make_state(1);
  plant.settle(st, 1.0e6);
  EXPECT_NEAR(rad_to_deg(st.s.gap_rad), 1.2, 1e-12);
  const double m = st.s.theta_motor_rad;
  for (int k = 0; k < 1999; ++k) plant.step(st, {m, m, kNaN}, 1e-3);
  EXPECT_NEAR(rad_to_deg(st.s.gap_rad), 1.2 + 0.01 * 1.999, 1e-9);
  plant.step(st, {m, m, kNaN}, 1e-3);
  EXPECT_NEAR(rad_to_deg(st.s.gap_rad), 1.7 + 0.01 * 2.0, 1e-9);
}

TEST(Effects, InputGapProgramOverridesTheModel) {
  const Plant plant = quiet(nominal());
  PlantState st = plant.make_state(1);
  plant.settle(st, 1.0e6);
  plant.step(st, {st.s.theta_cmd_rad, kNaN, deg_to_rad(2.0)}, 1e-3);
  EXPECT_NEAR(rad_to_deg(st.s.gap_rad), 2.0, 1e-12);
  plant.step(st, {st.s.theta_cmd_rad, kNaN, kNaN}, 1e-3);
  EXPECT_NEAR(rad_to_deg(st.s.gap_rad), 1.0, 1e-12);
}

TEST(Effects, EveryRegisteredEffectRoundTripsThroughYaml) {
  Plant plant = nominal();
  for (const char* extra : {"transport_delay:\n  delay_s: 0.02\n", "sensor_lag:\n  time_constant_s: 0.01\n",
                            "sensor_bias:\n  offset_kpa: 3\n  gain: 1.01\n", "valve_offset:\n  offset_deg: 0.3\n",
                            "throat_erosion:\n  rate_mm2_per_s: 0.1\n",
                            "backlash_change:\n  gap_deg: 1.1\n  step_time_s: 3\n  step_deg: 0.2\n  drift_deg_per_s: 0\n"}) {
    const auto node = hil::cfg::Node::load_string(extra, "extra.yaml");
    const auto [name, block] = node.entries().front();
    plant = plant.with(find_effect(name)->from_yaml(block));
  }
  const std::string yaml = plant.to_yaml("round trip");
  const Plant again = Plant::from_yaml(hil::cfg::Node::load_string(yaml, "again.yaml"));
  EXPECT_EQ(again.to_yaml("round trip"), yaml);
  EXPECT_EQ(again.effects().size(), 11u);
  EXPECT_EQ(effect_names().size(), 11u);
}

TEST(Effects, PressureRangeSpansTheValveTravel) {
  const auto [lo, hi] = quiet(nominal()).pressure_range_pa();
  // Textbook closed form at the stops (140 mm^2 open, 40 mm^2 closed); the gas-density term
  // the textbook drops is 0.7 % at the closed end.
  const double k = 1700 * 0.005 / std::pow(1e6, 0.35) * 0.01 * 900;
  EXPECT_NEAR(lo / std::pow(k / 140e-6, 1 / 0.65), 1.0, 0.005);
  EXPECT_NEAR(hi / std::pow(k / 40e-6, 1 / 0.65), 1.0, 0.008);
  Plant plant = quiet(nominal());
  PlantState st = plant.make_state(1);
  EXPECT_THROW(plant.settle(st, 3.5e6), std::out_of_range);
  EXPECT_THROW(plant.settle(st, 0.2e6), std::out_of_range);
}

// A small chamber is a fast one: 3 mL has a time constant of about 80 us, a tenth of the 1 ms
// step. The step is split where it spans more than a time constant, so the pressure follows the
// valve as the equilibrium it settles to (the same end value as the 2 L chamber), never outside
// the valve's pressure range; unsplit it flipped between 1 Pa and 0.37 MPa every step.
TEST(Effects, ASmallFastChamberFollowsTheValveWithoutRinging) {
  auto with_volume = [](double litres) {
    const Plant base = quiet(nominal());
    std::vector<double> v;
    for (const auto& prm : base.find("gas_generator")->params()) v.push_back(prm.value);
    v.at(6) = litres;  // free_volume_l
    v.at(7) = 0;       // volume_growth: the same volume for the whole test
    return base.with(base.find("gas_generator")->with_params(v));
  };
  const Plant small = with_volume(0.003), large = with_volume(2.0);
  const auto [lo, hi] = small.pressure_range_pa();
  PlantState s_small = small.make_state(1), s_large = large.make_state(1);
  small.settle(s_small, 1.0e6);
  large.settle(s_large, 1.0e6);
  const double cmd = s_small.s.theta_cmd_rad + hil::units::deg_to_rad(4.0);  // open by 4 deg
  for (int k = 0; k < 2000; ++k) {
    small.step(s_small, {cmd, kNaN, kNaN}, 1e-3);
    large.step(s_large, {cmd, kNaN, kNaN}, 1e-3);
    ASSERT_GE(s_small.s.p_chamber_pa, 0.999 * lo) << "step " << k;
    ASSERT_LE(s_small.s.p_chamber_pa, 1.001 * hi) << "step " << k;
  }
  EXPECT_LT(s_small.s.p_chamber_pa, 0.95e6);  // the valve opened: the pressure fell
  EXPECT_NEAR(s_small.s.p_chamber_pa / s_large.s.p_chamber_pa, 1.0, 1e-3);
  // Its mass balance holds across the split steps as across whole ones.
  EXPECT_GT(s_small.s.mdot_out_kg_s, 0.0);
  EXPECT_NEAR(s_small.s.mdot_gen_kg_s / s_small.s.mdot_out_kg_s, 1.0, 1e-3);  // settled: what burns, flows out
}

// Parameters each within range can together give no steady state (the equilibrium overflows):
// refused when the plant file loads, naming it, not as "-nan to -nan MPa" when a run settles it.
TEST(Effects, AChamberWithNoSteadyStateIsRefusedWhenTheFileLoads) {
  std::string text = hil::test::slurp(hil::test::source_path("configs/plant/nominal.yaml"));
  const auto at = text.find("burning_area_m2: 0.01 ");
  ASSERT_NE(at, std::string::npos);
  text.replace(at, 22, "burning_area_m2: 1    ");
  try {
    (void)Plant::from_yaml(hil::cfg::Node::load_string(text, "big.yaml"));
    FAIL() << "a 1 m^2 grain in a 2 L chamber loaded";
  } catch (const hil::cfg::Error& e) {
    EXPECT_NE(std::string(e.what()).find("big.yaml:6:1: effects: these effects give the chamber no finite steady pressure"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
