// diagnose on real transducers (issue 37, points 1 and 2): the noise of a pressure transducer is
// coloured (an anti-alias filter makes it an AR(1), plus white ADC noise, in steps of the ADC).
//  - The noise model, from the data alone, gives the noise a perfect model leaves, at every colour
//    and level real instruments have (the second-difference estimate saw 1.41 of 2.5 kPa at phi 0.6).
//  - No false alarm: files with nothing missing say nothing_missing at every colour and level.
//  - A correct model on coloured noise is explained, at the floor.
//  - The criterion holds while a slow misfit of another effect remains: an effect whose removal
//    costs more than half the noise power earns its place; one that only fits noise does not.
// Files: closed-loop campaign runs written noise-free, then the transducer's noise added
// (scenarios.hpp add_sensor_noise), some without the encoder, one through another lab's logger.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "hil/analysis/noise_model.hpp"
#include "temp_file.hpp"
#include "workbench_test_util.hpp"

namespace {

using hil::plant::Plant;
using hil::test::Scenario;
using hil::test::SensorNoise;
using hil::test::with_block;
namespace fs = std::filesystem;

constexpr double kErosion = 0.012;  // mm^2/s: a slow misfit of a few times the noise power in 30 s

// A chamber-like pressure (steps and a slow sine through the 0.1 s dynamics) plus noise n.
std::vector<double> chamber_with_noise(const SensorNoise& n, double rate_hz, double duration_s = 30) {
  std::mt19937_64 rng(n.seed);
  std::normal_distribution<double> g(0, 1);
  const double dt = 1 / rate_hz;
  const double phi = n.filter_hz > 0 ? std::exp(-2 * std::numbers::pi * n.filter_hz * dt) : n.phi;
  std::vector<double> y;
  double p = 1.0e6, x = n.coloured_kpa * 1e3 * g(rng);
  for (double t = 0; t < duration_s; t += dt) {
    const double target = (std::fmod(t, 5) < 2.5 ? 1.0e6 : 1.5e6) + 2e5 * std::sin(0.7 * t);
    p += (target - p) * (1 - std::exp(-dt / 0.1));
    x = phi * x + std::sqrt(1 - phi * phi) * n.coloured_kpa * 1e3 * g(rng);
    double v = p + x + n.white_kpa * 1e3 * g(rng);
    if (n.step_kpa > 0) v = n.step_kpa * 1e3 * std::round(v / (n.step_kpa * 1e3));
    y.push_back(v);
  }
  return y;
}

std::vector<SensorNoise> instrument_noises() {
  std::vector<SensorNoise> out;
  // AR(1) at phi 0.3-0.8 and first-order anti-alias filters at 50-200 Hz (at 1 kHz), 1-5 kPa,
  // with white ADC noise and steps.
  out.push_back({.coloured_kpa = 2.5, .phi = 0.6, .seed = 1});  // the file: read as 1.41 kPa
  out.push_back({.coloured_kpa = 3.0, .phi = 0.6, .seed = 2});
  out.push_back({.coloured_kpa = 1.0, .phi = 0.3, .white_kpa = 0.3, .seed = 3});
  out.push_back({.coloured_kpa = 3.0, .phi = 0.8, .white_kpa = 0.5, .step_kpa = 0.5, .seed = 4});
  out.push_back({.coloured_kpa = 5.0, .filter_hz = 50, .white_kpa = 1.0, .step_kpa = 1.0, .seed = 5});
  out.push_back({.coloured_kpa = 2.0, .filter_hz = 100, .white_kpa = 1.0, .seed = 6});
  out.push_back({.coloured_kpa = 4.0, .filter_hz = 200, .white_kpa = 0.5, .step_kpa = 0.2, .seed = 7});
  return out;
}

std::string text_of(const SensorNoise& n) {
  char b[200];
  std::snprintf(b, sizeof b, "coloured %.1f kPa (phi %.2f, filter %.0f Hz) + white %.1f kPa, step %.1f kPa", n.coloured_kpa,
                n.phi, n.filter_hz, n.white_kpa, n.step_kpa);
  return b;
}

// The noise a perfect model leaves, from the measured pressure alone, within 6 % at every colour
// and level above (before: within 4 % for white noise only; 1.41 kPa for 2.5 kPa at phi 0.6).
TEST(NoiseModel, TheNoiseAPerfectModelLeavesFromTheDataAlone) {
  for (const auto& n : instrument_noises()) {
    const double truth_pa = 1e3 * n.total_kpa();
    EXPECT_NEAR(hil::analysis::noise_sigma_from_data(chamber_with_noise(n, 1000)), truth_pa, 0.06 * truth_pa) << text_of(n);
  }
  // A 50 Hz filter logged at 2 kHz (phi 0.855 per row).
  const SensorNoise fast{.coloured_kpa = 3.0, .filter_hz = 50, .white_kpa = 0.5, .seed = 8};
  std::vector<double> y = chamber_with_noise(fast, 2000);
  EXPECT_NEAR(hil::analysis::noise_model_from_data(y, 5e-4).sigma_pa, 1e3 * fast.total_kpa(), 0.06e3 * fast.total_kpa());
}

// White noise stays white (no colour read into the scatter: a colour that is not there would
// raise the floor), and the colour that is there is found with its pole and corner frequency.
TEST(NoiseModel, WhiteStaysWhiteAndTheColourIsNamed) {
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    const SensorNoise white{.white_kpa = 2.0, .step_kpa = seed % 2 ? 0.0 : 1.0, .seed = seed};
    const auto m = hil::analysis::noise_model_from_data(chamber_with_noise(white, 1000), 1e-3);
    EXPECT_FALSE(m.coloured()) << "seed " << seed << ": " << m.method;
    EXPECT_NEAR(m.sigma_pa, 1e3 * white.total_kpa(), 0.04e3 * white.total_kpa()) << m.method;
  }
  const SensorNoise filtered{.coloured_kpa = 3.0, .filter_hz = 100, .white_kpa = 0.5, .seed = 9};
  const auto m = hil::analysis::noise_model_from_data(chamber_with_noise(filtered, 1000), 1e-3);
  EXPECT_TRUE(m.coloured()) << m.method;
  EXPECT_NEAR(m.phi, std::exp(-2 * std::numbers::pi * 100e-3), 0.05) << m.method;
  EXPECT_NEAR(m.corner_hz(), 100, 20) << m.method;
  EXPECT_NE(m.method.find("corner"), std::string::npos) << m.method;
}

// Coloured noise logged in ADC steps as coarse as itself (issue 37: the hidden-effect suite's DAQ
// files at 1 kPa in 1 kPa steps, every one a false alarm). 1 kPa of AR(1) or filtered noise plus
// 0.3 kPa white dithers 1 kPa steps (s = 1.04 q: the quantisation error's variance varies with the
// pressure by 1e-9 of itself, noise_model.cpp), so the reading is the noise plus a white error of
// q^2/12, and a perfect model leaves sqrt(1 + 0.09 + 1/12) = 1.083 kPa. Read as white from second
// differences it was 0.60-0.90 kPa (0.64 behind 50 Hz): the floor too good, a healthy file
// `unexplained`. Within 8 %: the estimate's own scatter from 30 s at 1 kHz is 1.6 % (1 sd) at phi
// 0.8 (30 000 rows (1 - phi)/(1 + phi) = 3 300 independent ones give the variance to 2.5 %, the
// median 1.3 times that on sigma), the chamber's steps add up to 3 %, and 8 % stays under the
// 10 % the verdict allows before a fit at the floor is called above it (kFloorTolerance).
// The other side: 300 Pa of white noise in the same steps does not dither them (the error's
// variance varies by 21 % with the pressure) and must stay white at its own 0.416 kPa (the median
// of its differences read 0.79 kPa of colour, the second differences 0.36).
TEST(NoiseModel, ColouredNoiseInADCStepsAsCoarseAsItself) {
  std::vector<SensorNoise> noises;
  for (const double phi : {0.3, 0.6, 0.8}) noises.push_back({.coloured_kpa = 1.0, .phi = phi, .white_kpa = 0.3, .step_kpa = 1.0});
  for (const double hz : {50.0, 200.0})
    noises.push_back({.coloured_kpa = 1.0, .filter_hz = hz, .white_kpa = 0.3, .step_kpa = 1.0});
  for (SensorNoise n : noises) {
    for (std::uint64_t seed = 1; seed <= 3; ++seed) {
      n.seed = 700 + seed;
      const auto m = hil::analysis::noise_model_from_data(chamber_with_noise(n, 1000), 1e-3);
      const double truth_pa = 1e3 * n.total_kpa();
      EXPECT_NEAR(m.sigma_pa, truth_pa, 0.08 * truth_pa) << text_of(n) << ", seed " << n.seed << ": " << m.method;
    }
  }
  for (std::uint64_t seed = 1; seed <= 3; ++seed) {
    const SensorNoise coarse{.white_kpa = 0.3, .step_kpa = 1.0, .seed = 710 + seed};
    const auto m = hil::analysis::noise_model_from_data(chamber_with_noise(coarse, 1000), 1e-3);
    EXPECT_FALSE(m.coloured()) << m.method;
    EXPECT_NEAR(m.sigma_pa, 1e3 * coarse.total_kpa(), 0.08e3 * coarse.total_kpa()) << m.method;
  }
}

// The whitening filter turns the noise into white noise of unit variance: the criterion counts a
// perfect model's residual as N independent samples of the noise's one-step prediction error.
TEST(NoiseModel, WhitenedNoiseIsWhiteWithUnitVariance) {
  const SensorNoise n{.coloured_kpa = 3.0, .phi = 0.7, .white_kpa = 1.0, .seed = 10};
  const std::vector<double> y = chamber_with_noise(n, 1000);
  const auto m = hil::analysis::noise_model_from_data(y, 1e-3);
  std::vector<double> noise_only(y.size());
  {
    SensorNoise quiet = n;  // the same seed: the same noise on a chamber without it
    quiet.coloured_kpa = quiet.white_kpa = 0;
    const std::vector<double> p = chamber_with_noise(quiet, 1000);
    for (std::size_t k = 0; k < y.size(); ++k) noise_only[k] = y[k] - p[k];
  }
  std::vector<double> w(y.size());
  m.whiten(noise_only, w);
  double s0 = 0, s1 = 0;
  for (std::size_t k = 2; k < w.size(); ++k) s0 += w[k] * w[k], s1 += w[k] * w[k - 1];
  EXPECT_NEAR(s0 / static_cast<double>(w.size() - 2), 1.0, 0.08) << m.method;
  EXPECT_NEAR(s1 / s0, 0.0, 0.05) << m.method;
  EXPECT_NEAR(m.whitened_rss(noise_only), s0 + w[1] * w[1], 1e-6 * s0);
}

class Files : public testing::Test {
 protected:
  hil::test::TempDir dir;
  // A closed-loop run written noise-free, then the transducer's noise added.
  fs::path make(Scenario s, const SensorNoise& n) {
    s.noise_kpa = 0;
    const fs::path f = hil::test::make_measurement(s, dir.path());
    hil::test::add_sensor_noise(f, n);
    return f;
  }
  nlohmann::json diagnose(const fs::path& data, const std::string& name) {
    const auto t0 = std::chrono::steady_clock::now();
    auto d = hil::test::run_diagnose(hil::test::nominal_model(), data, dir.path() / ("out_" + name));
    std::printf("[ diagnose ] %s: %s, fit %.2f %% (floor %.2f %%), noise %.3g kPa, %.1f s\n", name.c_str(),
                d.at("verdict").get<std::string>().c_str(), d.at("fit_after_pct").get<double>(),
                d.at("noise_floor_fit_pct").get<double>(), d.at("noise_sigma_kpa").get<double>(),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    return d;
  }
};

// No false alarm: nothing is missing from the model, the noise is a real transducer's. Before,
// 3 kPa of AR(1) noise with nothing hidden was called `unexplained`.
TEST_F(Files, HealthyFilesSayNothingMissingAtEveryColourAndLevel) {
  const auto noises = instrument_noises();
  int false_alarms = 0;
  for (std::size_t i = 0; i < noises.size(); ++i) {
    Scenario s;
    s.name = "healthy_" + std::to_string(i);
    s.seed = 300 + i;
    s.encoder = i % 2 == 0;
    s.compensation = i % 3 == 0 ? "adaptive" : (i % 3 == 1 ? "constant" : "none");
    s.reference_yaml =
        i % 2 ? hil::test::reference_random(40 + i, 0.8, 1.6, 1.0, 3.5) : hil::test::reference_ramps(0.9, 1.5, 4.0);
    const auto d = diagnose(make(s, noises[i]), s.name);
    const bool ok = d.at("verdict") == "nothing_missing" && d.at("added").empty();
    false_alarms += ok ? 0 : 1;
    EXPECT_TRUE(ok) << text_of(noises[i]) << ": " << hil::test::brief(d);
  }
  // Another lab's logger (jittered rows, a time offset, CRLF, text columns) with a 100 Hz filter.
  hil::test::LabLog lab;
  lab.name = "healthy_lab";
  lab.noise_kpa = 0;
  lab.seed = 31;
  const fs::path f = hil::test::make_lab_log(lab, dir.path());
  hil::test::add_sensor_noise(f, {.coloured_kpa = 2.5, .filter_hz = 100, .white_kpa = 0.5, .seed = 32});
  const auto d = diagnose(f, "healthy_lab");
  const bool ok = d.at("verdict") == "nothing_missing" && d.at("added").empty();
  false_alarms += ok ? 0 : 1;
  EXPECT_TRUE(ok) << hil::test::brief(d);
  std::printf("[ measured ] false alarms on healthy coloured-noise files: %d of %zu\n", false_alarms, noises.size() + 1);
}

// A correct model on coloured noise is explained at the floor (before: a file whose model was
// exactly right, one 18 ms sensor lag, was `partly_explained` at "1.76x the noise").
TEST_F(Files, AHiddenEffectOnColouredNoiseIsExplainedAtTheFloor) {
  Scenario s;
  s.name = "lag_coloured";
  s.seed = 401;
  s.encoder = true;
  s.compensation = "constant";
  s.reference_yaml = hil::test::reference_square(0.9, 1.5, 2.5);
  s.truth = [](const Plant& p) { return with_block(p, "sensor_lag", "time_constant_s: 0.018"); };
  const auto d = diagnose(make(s, {.coloured_kpa = 2.5, .phi = 0.6, .seed = 41}), s.name);
  EXPECT_EQ(d.at("verdict"), "explained") << hil::test::brief(d);
  EXPECT_TRUE(d.at("at_noise_floor").get<bool>()) << hil::test::brief(d);
  ASSERT_EQ(d.at("added").size(), 1u) << hil::test::brief(d);
  EXPECT_NEAR(hil::test::added_param(d, "sensor_lag", "time_constant_s"), 0.018, 0.15 * 0.018) << hil::test::brief(d);

  Scenario g;
  g.name = "gap_filtered";
  g.seed = 402;
  g.encoder = false;
  g.compensation = "adaptive";
  g.reference_yaml = hil::test::reference_random(43, 0.9, 1.5, 1.5, 3.0);
  g.truth = [](const Plant& p) { return with_block(p, "backlash_change", "gap_deg: 1.6"); };
  const auto dg =
      diagnose(make(g, {.coloured_kpa = 3.0, .filter_hz = 50, .white_kpa = 0.5, .step_kpa = 0.5, .seed = 44}), g.name);
  EXPECT_EQ(dg.at("verdict"), "explained") << hil::test::brief(dg);
  ASSERT_FALSE(dg.at("added").empty()) << hil::test::brief(dg);
  EXPECT_EQ(dg.at("added")[0].at("effect"), "backlash_change") << hil::test::brief(dg);
  EXPECT_NEAR(hil::test::added_param(dg, "backlash_change", "gap_deg"), 1.6, 0.15 * 1.6) << hil::test::brief(dg);
}

// The criterion while a slow misfit remains (issue 37 point 2). The file has an erosion (a slow,
// growing misfit) and a 15 ms sensor lag; diagnose may only try the lag, so the erosion's misfit
// stays in the residual all along. The lag's removal from the true model costs more than half the
// noise power (asserted from the data): it must earn its place. Before, the residual's effective
// sample size collapsed under the slow misfit and the lag did not. Other side: the same file
// without the lag; the lag only fits noise (and whatever of the erosion it can) and must not.
TEST_F(Files, AnEffectEarnsItsPlaceWhileASlowMisfitRemains) {
  const SensorNoise noise{.coloured_kpa = 2.0, .phi = 0.6, .white_kpa = 0.5, .seed = 51};
  const Plant nominal = Plant::load(hil::test::nominal_model());
  auto eroded = [](const Plant& p) { return with_block(p, "throat_erosion", "rate_mm2_per_s: " + std::to_string(kErosion)); };
  auto lagged = [](const Plant& p) { return with_block(p, "sensor_lag", "time_constant_s: 0.015"); };
  hil::analysis::DiagnoseSettings only_lag;
  only_lag.candidates = {"sensor_lag"};
  only_lag.keep_series = false;
  for (const bool with_lag : {true, false}) {
    Scenario s;
    s.name = with_lag ? "slow_misfit_lag" : "slow_misfit_only";
    s.seed = 501;
    s.encoder = true;
    s.compensation = "constant";
    s.reference_yaml = hil::test::reference_random(57, 0.9, 1.5, 1.0, 2.5);
    s.truth = [&](const Plant& p) { return with_lag ? lagged(eroded(p)) : eroded(p); };
    const auto m = hil::analysis::load_measurement(make(s, noise));
    // The premise, from the data: what each effect's absence costs, in units of the noise power.
    const double noise_power = static_cast<double>(m.rows.size()) * std::pow(1e3 * noise.total_kpa(), 2);
    auto rss = [&](const Plant& model) {
      const auto r = hil::analysis::compare_measurement(model, m, false);
      return r.error.rmse_pa * r.error.rmse_pa * static_cast<double>(r.rows);
    };
    const double truth_rss = rss(s.truth(nominal));
    const double erosion_cost = (rss(with_lag ? lagged(nominal) : nominal) - truth_rss) / noise_power;
    const double lag_cost = with_lag ? (rss(eroded(nominal)) - truth_rss) / noise_power : 0.0;
    std::printf("[ premise  ] %s: dropping the erosion costs %.2f, the lag %.2f times the noise power\n", s.name.c_str(),
                erosion_cost, lag_cost);
    ASSERT_GT(erosion_cost, 1.0) << "the slow misfit is there";
    if (with_lag) {
      ASSERT_GT(lag_cost, 0.5) << "the lag costs more than half the noise power";
      ASSERT_LT(lag_cost, erosion_cost) << "the slow misfit is the larger one";
    }
    const auto t0 = std::chrono::steady_clock::now();
    const hil::analysis::Diagnosis d = hil::analysis::diagnose(nominal, m, only_lag);
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::string why;
    for (const auto& r : d.rounds)
      for (const auto& c : r.ranking) why += c.effect + " dBIC " + std::to_string(c.delta_bic) + " " + c.why_not + "; ";
    std::printf("[ diagnose ] %s: %s, %.1f s; %s\n", s.name.c_str(), d.verdict.c_str(), wall, why.c_str());
    if (with_lag) {
      ASSERT_EQ(d.added.size(), 1u) << why;
      EXPECT_EQ(d.added[0].effect, "sensor_lag");
      EXPECT_NEAR(d.added[0].parameters.at(0).value, 0.015, 0.15 * 0.015) << why;
    } else {
      EXPECT_TRUE(d.added.empty()) << why;
      EXPECT_EQ(d.verdict, "unexplained") << why;
    }
  }
}

// The four-effect file, on AR(1) noise, with the full search: a drifting gap, a 15 ms
// sensor lag, erosion and a 3 % sensor gain, encoder logged. Before, the effective sample size fell
// to 11-24 of 30 000 rows and the search stopped without the lag; with the prewhitened criterion the
// search chose a gap step for the drift in round 3, which left the lag 8.6 % of the excess, and
// stopped at 97.5 % (floor 98.3 %) until it went forward again after the revision made the gap a
// drift. (The gain and a burn-rate change differ only through the chamber's dynamics: not asserted.)
TEST_F(Files, FourEffectsOnColouredNoiseAreAllFound) {
  Scenario s;
  s.name = "four_coloured";
  s.seed = 601;
  s.encoder = true;
  s.compensation = "constant";
  s.reference_yaml = hil::test::reference_random(91, 0.9, 1.5, 1.0, 3.0);
  s.truth = [](const Plant& p) {
    return with_block(with_block(with_block(with_block(p, "backlash_change", "{gap_deg: 1.0, drift_deg_per_s: 0.02}"),
                                            "sensor_lag", "time_constant_s: 0.015"),
                                 "throat_erosion", "rate_mm2_per_s: 0.3"),
                      "sensor_bias", "gain: 1.03");
  };
  const auto d = diagnose(make(s, {.coloured_kpa = 2.5, .phi = 0.6, .seed = 61}), s.name);
  EXPECT_EQ(d.at("verdict"), "explained") << hil::test::brief(d);
  EXPECT_NEAR(hil::test::added_param(d, "sensor_lag", "time_constant_s"), 0.015, 0.15 * 0.015) << hil::test::brief(d);
  EXPECT_NEAR(hil::test::added_param(d, "throat_erosion", "rate_mm2_per_s"), 0.3, 0.15 * 0.3) << hil::test::brief(d);
  EXPECT_NEAR(hil::test::added_param(d, "backlash_change", "drift_deg_per_s"), 0.02, 0.15 * 0.02) << hil::test::brief(d);
}

}  // namespace
