// Hidden-effect acceptance tests of `diagnose`: measurement files are made from the plant with an
// effect switched on that configs/plant/nominal.yaml does not have; the workbench gets only the CSV
// and the nominal model file. Asserted per file: the top-ranked effect is the hidden one, its
// fitted parameter is within 15 % of the truth, and the fit after adding it is within 1 point of
// the noise floor; the written model, compared again, shows the lower error.
// Also: two effects at once (both found, in turn), an effect outside the candidate list
// (explained false, nothing named, the signature reported), no effect (nothing added), and
// another lab's logger file (non-uniform dt, other columns, CRLF, a time offset).
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "temp_file.hpp"
#include "workbench_test_util.hpp"

namespace {

using hil::plant::Plant;
using hil::test::Scenario;
using hil::test::with_block;
using hil::test::with_param;
namespace fs = std::filesystem;

// Soak runs: HIL_ANALYSIS_SEED_OFFSET=N shifts every noise seed and random reference by N.
std::uint64_t seed_shift() {
  const char* env = std::getenv("HIL_ANALYSIS_SEED_OFFSET");
  return env ? std::strtoull(env, nullptr, 10) : 0;
}

struct Expect {
  std::string key;  // parameter of the top-ranked effect
  double truth;
  // A step time: placed only between the motions around it, so the truth must lie within the
  // reported span of values that fit as well, not within 15 % of the best one.
  bool within_span = false;
};

struct HiddenCase {
  Scenario scenario;
  std::string effect;          // expected top-ranked effect
  std::vector<Expect> params;  // each within 15 % of the truth
};

std::string name_of(const testing::TestParamInfo<HiddenCase>& info) { return info.param.scenario.name; }
void PrintTo(const HiddenCase& c, std::ostream* os) { *os << c.scenario.name << " (" << c.effect << ")"; }

std::vector<HiddenCase> cases() {
  using hil::test::reference_ramps;
  using hil::test::reference_square;
  std::vector<HiddenCase> out;
  const std::uint64_t shift = seed_shift();
  auto reference_random = [shift](std::uint64_t seed, double lo, double hi, double dwell_lo, double dwell_hi) {
    return hil::test::reference_random(seed + shift, lo, hi, dwell_lo, dwell_hi);
  };
  auto add = [&](std::string name, std::string effect, std::vector<Expect> params, std::uint64_t seed, std::string ref,
                 bool encoder, double noise_kpa, std::string compensation, std::function<Plant(const Plant&)> truth) {
    Scenario s;
    s.name = std::move(name);
    s.seed = seed + shift;
    s.reference_yaml = std::move(ref);
    s.encoder = encoder;
    s.noise_kpa = noise_kpa;
    s.compensation = std::move(compensation);
    s.truth = std::move(truth);
    out.push_back({s, std::move(effect), std::move(params)});
  };
  add("backlash_gap", "backlash_change", {{"gap_deg", 1.8}}, 101, reference_square(1.0, 1.4, 3.0), true, 2.0, "adaptive",
      [](const Plant& p) { return with_block(p, "backlash_change", "gap_deg: 1.8"); });
  add("backlash_step", "backlash_change", {{"gap_deg", 1.0}, {"step_deg", 1.0}, {"step_time_s", 14, true}}, 102,
      reference_random(5, 0.9, 1.5, 1.5, 4.0), false, 2.5, "adaptive",
      [](const Plant& p) { return with_block(p, "backlash_change", "{gap_deg: 1.0, step_time_s: 14, step_deg: 1.0}"); });
  add("valve_offset", "valve_offset", {{"offset_deg", 1.5}}, 103, reference_ramps(0.95, 1.45, 5.0), false, 2.0, "none",
      [](const Plant& p) { return with_block(p, "valve_offset", "offset_deg: 1.5"); });
  add("throat_erosion", "throat_erosion", {{"rate_mm2_per_s", 0.5}}, 104, reference_random(9, 0.9, 1.3, 2.0, 5.0), true, 1.5,
      "adaptive", [](const Plant& p) { return with_block(p, "throat_erosion", "rate_mm2_per_s: 0.5"); });
  add("sensor_lag", "sensor_lag", {{"time_constant_s", 0.03}}, 105, reference_square(0.9, 1.5, 2.5), true, 2.0, "constant",
      [](const Plant& p) { return with_block(p, "sensor_lag", "time_constant_s: 0.03"); });
  add("transport_delay", "transport_delay", {{"delay_s", 0.025}}, 106, reference_random(13, 0.9, 1.5, 1.5, 3.5), false, 2.0,
      "adaptive", [](const Plant& p) { return with_block(p, "transport_delay", "delay_s: 0.025"); });
  add("sensor_bias", "sensor_bias", {{"offset_kpa", 30}, {"gain", 1.03}}, 107, reference_ramps(1.0, 1.5, 6.0), true, 3.0, "none",
      [](const Plant& p) { return with_block(p, "sensor_bias", "{offset_kpa: 30, gain: 1.03}"); });
  add("servo_lag", "motor_dynamics", {{"time_constant_s", 0.035}}, 108, reference_square(1.0, 1.5, 2.0), false, 2.0, "adaptive",
      [](const Plant& p) { return with_param(p, "motor_servo", "time_constant_s", 0.035); });
  // The rate limit shows only when the drive is asked to move fast: large reference steps, and
  // the compensator's jumps across the gap.
  add("servo_rate", "motor_dynamics", {{"rate_limit_deg_s", 25}}, 109, reference_square(0.9, 1.6, 3.0), false, 2.0, "adaptive",
      [](const Plant& p) { return with_param(p, "motor_servo", "rate_limit_deg_s", 25); });
  add("burn_rate_a", "burn_rate", {{"burn_rate_mm_s_at_1mpa", 5.4}}, 110, reference_square(0.95, 1.35, 3.5), true, 2.0,
      "adaptive", [](const Plant& p) { return with_param(p, "gas_generator", "burn_rate_mm_s_at_1mpa", 5.4); });
  add("burn_rate_n", "burn_rate", {{"pressure_exponent", 0.40}}, 111, reference_random(21, 0.9, 1.6, 2.0, 4.0), false, 2.0,
      "adaptive", [](const Plant& p) { return with_param(p, "gas_generator", "pressure_exponent", 0.40); });
  return out;
}

class HiddenEffect : public testing::TestWithParam<HiddenCase> {};

TEST_P(HiddenEffect, TopRankedIsTheHiddenOneAndTheErrorFalls) {
  const HiddenCase& c = GetParam();
  hil::test::TempDir dir;
  const fs::path data = hil::test::make_measurement(c.scenario, dir.path());
  if (const char* keep = std::getenv("HIL_ANALYSIS_KEEP")) {  // keep the generated file to look at
    fs::create_directories(keep);
    fs::copy_file(data, fs::path(keep) / data.filename(), fs::copy_options::overwrite_existing);
  }
  const fs::path fitted = dir.path() / "fitted.yaml";
  const auto d = hil::test::run_diagnose(hil::test::nominal_model(), data, dir.path() / "diag", fitted);
  const std::string why = hil::test::brief(d);

  // Precondition: the hidden effect shows in the data (else "nothing missing" would be right).
  ASSERT_LT(d.at("fit_before_pct").get<double>(), d.at("noise_floor_fit_pct").get<double>() - 1.0)
      << "the scenario does not exercise the hidden effect; " << why;
  ASSERT_FALSE(d.at("ranking").empty()) << why;
  const auto& top = d.at("ranking")[0];
  EXPECT_EQ(top.at("effect"), c.effect) << why;
  EXPECT_TRUE(d.at("explained").get<bool>()) << why;
  ASSERT_EQ(d.at("added").size(), 1u) << why;
  EXPECT_EQ(d.at("added")[0].at("effect"), c.effect) << why;
  for (const auto& e : c.params) {
    const double v = hil::test::param(d.at("added")[0], e.key);
    if (e.within_span) {
      const auto span = hil::test::param_entry(d.at("added")[0], e.key).at("fits_within_one_sigma");
      EXPECT_LE(span[0].get<double>(), e.truth) << span << "; " << why;
      EXPECT_GE(span[1].get<double>(), e.truth) << span << "; " << why;
      EXPECT_TRUE(span[0].get<double>() <= v && v <= span[1].get<double>()) << span << " " << v;
      std::printf("[ %s ] %s = %.5g, fits as well from %.5g to %.5g (truth %.5g)\n", c.scenario.name.c_str(), e.key.c_str(), v,
                  span[0].get<double>(), span[1].get<double>(), e.truth);
      continue;
    }
    EXPECT_NEAR(v, e.truth, 0.15 * std::abs(e.truth)) << e.key << "; " << why;
    std::printf("[ %s ] %s = %.5g (truth %.5g, %+.2f %%)\n", c.scenario.name.c_str(), e.key.c_str(), v, e.truth,
                100 * (v - e.truth) / e.truth);
  }
  const double floor = d.at("noise_floor_fit_pct").get<double>();
  const double before = d.at("fit_before_pct").get<double>(), after = d.at("fit_after_pct").get<double>();
  EXPECT_GE(after, floor - 1.0) << why;
  EXPECT_GT(after, before) << why;
  std::printf("[ %s ] fit before %.2f %%, after %.2f %%, noise floor %.2f %%, encoder %s, %.1f s\n", c.scenario.name.c_str(),
              before, after, floor, c.scenario.encoder ? "yes" : "no", d.at("method").at("wall_s").get<double>());

  // Add it and watch the error fall: compare on the written model.
  const auto nominal = hil::test::run_compare(hil::test::nominal_model(), data, dir.path() / "cmp_nominal");
  const auto again = hil::test::run_compare(fitted, data, dir.path() / "cmp_fitted");
  EXPECT_NEAR(nominal.at("fit_pct").get<double>(), before, 1e-6);
  EXPECT_NEAR(again.at("fit_pct").get<double>(), after, 1e-6);
  EXPECT_LT(again.at("rmse_kpa").get<double>(), nominal.at("rmse_kpa").get<double>());
}

INSTANTIATE_TEST_SUITE_P(Candidates, HiddenEffect, testing::ValuesIn(cases()), name_of);

TEST(HiddenEffects, TwoEffectsAreFoundInTurn) {
  hil::test::TempDir dir;
  Scenario s;
  s.name = "offset_and_lag";
  s.seed = 112 + seed_shift();
  s.reference_yaml = hil::test::reference_random(33 + seed_shift(), 0.9, 1.5, 1.5, 4.0);
  s.encoder = false;
  s.truth = [](const Plant& p) {
    return with_block(with_block(p, "valve_offset", "offset_deg: 1.2"), "sensor_lag", "time_constant_s: 0.04");
  };
  const fs::path data = hil::test::make_measurement(s, dir.path());
  const auto d = hil::test::run_diagnose(hil::test::nominal_model(), data, dir.path() / "diag", dir.path() / "fitted.yaml");
  const std::string why = hil::test::brief(d);
  ASSERT_EQ(d.at("added").size(), 2u) << why;
  std::vector<std::string> found = {d.at("added")[0].at("effect"), d.at("added")[1].at("effect")};
  std::sort(found.begin(), found.end());
  EXPECT_EQ(found, (std::vector<std::string>{"sensor_lag", "valve_offset"})) << why;
  // In turn: one per round, the second against the model with the first.
  ASSERT_GE(d.at("rounds").size(), 2u);
  EXPECT_EQ(d.at("rounds")[0].at("added"), d.at("added")[0].at("effect"));
  EXPECT_EQ(d.at("rounds")[1].at("added"), d.at("added")[1].at("effect"));
  for (const auto& a : d.at("added")) {
    if (a.at("effect") == "valve_offset") {
      EXPECT_NEAR(hil::test::param(a, "offset_deg"), 1.2, 0.18) << why;
    }
    if (a.at("effect") == "sensor_lag") {
      EXPECT_NEAR(hil::test::param(a, "time_constant_s"), 0.04, 0.006) << why;
    }
  }
  EXPECT_GE(d.at("fit_after_pct").get<double>(), d.at("noise_floor_fit_pct").get<double>() - 1.0) << why;
  EXPECT_EQ(d.at("verdict"), "explained") << why;
  std::printf("[ two effects ] fit %.2f -> %.2f %% (floor %.2f %%), %s then %s\n", d.at("fit_before_pct").get<double>(),
              d.at("fit_after_pct").get<double>(), d.at("noise_floor_fit_pct").get<double>(),
              d.at("added")[0].at("effect").get<std::string>().c_str(), d.at("added")[1].at("effect").get<std::string>().c_str());
}

TEST(HiddenEffects, AnEffectOutsideTheListIsNotNamed) {
  hil::test::TempDir dir;
  Scenario s;
  s.name = "oscillation";
  s.seed = 113 + seed_shift();
  s.reference_yaml = hil::test::reference_square(1.0, 1.45, 3.0);
  s.truth = [](const Plant& p) { return with_block(p, "test_chamber_oscillation", "{amplitude_kpa: 12, frequency_hz: 11.3}"); };
  const fs::path data = hil::test::make_measurement(s, dir.path());
  const auto d = hil::test::run_diagnose(hil::test::nominal_model(), data, dir.path() / "diag", dir.path() / "fitted.yaml");
  const std::string why = hil::test::brief(d);
  EXPECT_FALSE(d.at("explained").get<bool>()) << why;
  EXPECT_EQ(d.at("verdict"), "unexplained") << why;
  EXPECT_TRUE(d.at("added").empty()) << why;
  for (const auto& c : d.at("ranking")) EXPECT_FALSE(c.at("earns_place").get<bool>()) << why;
  // The summary says so plainly and names no candidate; the signature points at the spectrum.
  const std::string summary = d.at("summary")[0];
  EXPECT_NE(summary.find("No candidate explains"), std::string::npos) << summary;
  for (const auto& name : hil::analysis::builtin_candidate_names()) {
    for (const auto& line : d.at("summary")) EXPECT_EQ(line.get<std::string>().find(name), std::string::npos) << line;
  }
  ASSERT_FALSE(d.at("signature_peaks").empty()) << why;
  EXPECT_NEAR(d.at("signature_peaks")[0].at("hz").get<double>(), 11.3, 0.5);
  EXPECT_GT(d.at("signature_peaks")[0].at("power_share").get<double>(), 0.5);
  bool spectrum_line = false;
  for (const auto& line : d.at("signature")) spectrum_line |= line.get<std::string>().find("11.") != std::string::npos;
  EXPECT_TRUE(spectrum_line) << why;
  // The written model is the nominal one, unchanged.
  const Plant fitted = Plant::load(dir.path() / "fitted.yaml");
  EXPECT_EQ(fitted.effects().size(), Plant::load(hil::test::nominal_model()).effects().size());
  std::printf("[ outside the list ] fit %.2f %% (floor %.2f %%): %s\n", d.at("fit_before_pct").get<double>(),
              d.at("noise_floor_fit_pct").get<double>(), d.at("signature_peaks")[0].at("name").get<std::string>().c_str());
}

TEST(HiddenEffects, NoEffectAddsNothing) {
  hil::test::TempDir dir;
  Scenario s;
  s.name = "nominal_truth";
  s.seed = 114 + seed_shift();
  s.reference_yaml = hil::test::reference_ramps(0.9, 1.5, 4.0);
  s.encoder = false;
  s.noise_kpa = 2.5;
  const fs::path data = hil::test::make_measurement(s, dir.path());
  const auto d = hil::test::run_diagnose(hil::test::nominal_model(), data, dir.path() / "diag");
  const std::string why = hil::test::brief(d);
  EXPECT_TRUE(d.at("added").empty()) << why;
  EXPECT_EQ(d.at("verdict"), "nothing_missing") << why;
  for (const auto& c : d.at("ranking")) EXPECT_FALSE(c.at("earns_place").get<bool>()) << why;
  EXPECT_GE(d.at("fit_before_pct").get<double>(), d.at("noise_floor_fit_pct").get<double>() - 0.2) << why;
}

TEST(HiddenEffects, AnotherLabsLoggerWithJitteredTime) {
  hil::test::TempDir dir;
  hil::test::LabLog lab;
  lab.seed += seed_shift();
  lab.truth = [](const Plant& p) { return with_block(p, "valve_offset", "offset_deg: -1.0"); };
  const fs::path data = hil::test::make_lab_log(lab, dir.path());
  const auto d = hil::test::run_diagnose(hil::test::nominal_model(), data, dir.path() / "diag");
  const std::string why = hil::test::brief(d);
  ASSERT_EQ(d.at("added").size(), 1u) << why;
  EXPECT_EQ(d.at("ranking")[0].at("effect"), "valve_offset") << why;
  EXPECT_NEAR(hil::test::param(d.at("added")[0], "offset_deg"), -1.0, 0.15) << why;
  EXPECT_GE(d.at("fit_after_pct").get<double>(), d.at("noise_floor_fit_pct").get<double>() - 1.0) << why;
  EXPECT_EQ(d.at("verdict"), "explained") << why;
  EXPECT_NEAR(d.at("time_origin_s").get<double>(), lab.t0_s, 1e-9);
  std::printf("[ lab logger ] offset %.4f deg (truth -1), fit %.2f -> %.2f %% (floor %.2f %%)\n",
              hil::test::param(d.at("added")[0], "offset_deg"), d.at("fit_before_pct").get<double>(),
              d.at("fit_after_pct").get<double>(), d.at("noise_floor_fit_pct").get<double>());
}

}  // namespace
