// The workbench's pieces against what they must do: measurement files (bad input named by file,
// line and column; extra columns ignored; non-uniform time), the noise estimate, the metrics and
// diagnostics on residuals of known shape, the replay (streamed and in memory agree; the bench's
// own telemetry round-trips at the noise floor), and the hilbench command line.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <numbers>
#include <random>
#include <sstream>

#include "hil/analysis/candidates.hpp"
#include "hil/analysis/compare.hpp"
#include "hil/analysis/diagnose.hpp"
#include "hil/analysis/measurement.hpp"
#include "hil/analysis/replay.hpp"
#include "hil/analysis/residuals.hpp"
#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/campaign/sim.hpp"
#include "hil/config.hpp"
#include "hil/csv_reader.hpp"
#include "hil/units.hpp"
#include "temp_file.hpp"
#include "workbench_test_util.hpp"

namespace {

namespace fs = std::filesystem;
using hil::analysis::compare_file;
using hil::analysis::load_measurement;

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

hil::plant::Plant nominal() { return hil::plant::Plant::load(hil::test::nominal_model()); }

// A short valid file body: steady 1 MPa, 11.4 deg, n rows at 1 kHz.
std::string rows(int n, double t0 = 0) {
  std::string s;
  char b[120];
  for (int i = 0; i < n; ++i) {
    std::snprintf(b, sizeof b, "%.4f,11.41174,%.6f\n", t0 + i * 1e-3, 1.0 + 0.001 * std::sin(i));
    s += b;
  }
  return s;
}

// --- bad input ------------------------------------------------------------------------------

TEST(MeasurementFile, MissingRequiredColumnNamesFileLineAndColumn) {
  hil::test::TempDir dir;
  const auto f = dir.write("run.csv", "# source: lab\nt_s,theta_cmd_deg\n0,1\n");
  const std::string e = error_of([&] { load_measurement(f); });
  EXPECT_NE(e.find(f.string() + ":2:1"), std::string::npos) << e;
  EXPECT_NE(e.find("missing required column 'p_meas_mpa'"), std::string::npos) << e;
  EXPECT_EQ(error_of([&] { compare_file(nominal(), f); }), e);
}

TEST(MeasurementFile, NonNumericCellNamesFileLineAndColumn) {
  hil::test::TempDir dir;
  const auto f = dir.write("run.csv", "t_s,theta_cmd_deg,p_meas_mpa\n" + rows(3) + "0.0030,11.4,abc\n" + rows(60, 0.004));
  const std::string e = error_of([&] { compare_file(nominal(), f); });
  EXPECT_NE(e.find(f.string() + ":5:3"), std::string::npos) << e;
  EXPECT_NE(e.find("not a number: 'abc'"), std::string::npos) << e;
}

TEST(MeasurementFile, TimeGoingBackwardsNamesFileLineAndColumn) {
  hil::test::TempDir dir;
  const auto f = dir.write("run.csv", "theta_cmd_deg,t_s,p_meas_mpa\n11.4,0.000,1.0\n11.4,0.001,1.0\n11.4,0.0005,1.0\n");
  const std::string e = error_of([&] { load_measurement(f); });
  EXPECT_NE(e.find(f.string() + ":4:2"), std::string::npos) << e;
  EXPECT_NE(e.find("goes backwards"), std::string::npos) << e;
}

TEST(MeasurementFile, TooShortToFitNamesFileAndLine) {
  hil::test::TempDir dir;
  const auto f = dir.write("short.csv", "# a: b\nt_s,theta_cmd_deg,p_meas_mpa\n" + rows(10));
  for (const std::string& e : {error_of([&] { load_measurement(f); }), error_of([&] { compare_file(nominal(), f); })}) {
    EXPECT_NE(e.find(f.string() + ":12:1"), std::string::npos) << e;
    EXPECT_NE(e.find("only 10 data row(s)"), std::string::npos) << e;
  }
}

TEST(MeasurementFile, EmptyAndHeaderOnlyFilesAreClearErrors) {
  hil::test::TempDir dir;
  const auto empty = dir.write("empty.csv", "");
  std::string e = error_of([&] { compare_file(nominal(), empty); });
  EXPECT_NE(e.find(empty.string() + ":1:1"), std::string::npos) << e;
  EXPECT_NE(e.find("empty"), std::string::npos) << e;
  const auto header = dir.write("header.csv", "# source: x\n\nt_s,theta_cmd_deg,p_meas_mpa\n");
  for (const std::string& e2 :
       {error_of([&] { load_measurement(header); }), error_of([&] { compare_file(nominal(), header); })}) {
    EXPECT_NE(e2.find(header.string() + ":4:1"), std::string::npos) << e2;
    EXPECT_NE(e2.find("only 0 data row(s)"), std::string::npos) << e2;
  }
  e = error_of([&] { load_measurement(dir.path() / "absent.csv"); });
  EXPECT_NE(e.find("absent.csv"), std::string::npos) << e;
}

TEST(MeasurementFile, OtherColumnsAreIgnoredAndUnitsConverted) {
  hil::test::TempDir dir;
  const auto f = dir.write("lab.csv",
                           "# logger: X\r\nstatus,p_meas_mpa,t_s,theta_motor_deg,junk,theta_cmd_deg\r\n"
                           "OK,1.5,0.0,10,x,11\r\nOK,1.25,0.002,10,y,12\r\n");
  hil::analysis::MeasurementReader r(f);
  hil::analysis::MeasurementRows rows;
  ASSERT_TRUE(r.next(rows));
  EXPECT_TRUE(r.has_encoder());
  EXPECT_FALSE(r.has_reference());
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_DOUBLE_EQ(rows.p_meas_pa[1], 1.25e6);
  EXPECT_DOUBLE_EQ(rows.t_s[1], 0.002);
  EXPECT_NEAR(rows.theta_cmd_rad[1], 12 * std::numbers::pi / 180, 1e-15);
  EXPECT_NEAR(rows.theta_motor_rad[0], 10 * std::numbers::pi / 180, 1e-15);
}

// Rows at a given period, steady 1 MPa with a small wobble; `cell` replaces the pressure at row
// `at` (verbatim text), `jump_s` is added to every time from row `at` on.
std::string rows_with(int n, double period_s, int at = -1, const std::string& cell = "", double jump_s = 0) {
  std::string s;
  char b[160];
  for (int i = 0; i < n; ++i) {
    char p[64];
    std::snprintf(p, sizeof p, "%.6f", 1.0 + 0.001 * std::sin(i));
    const double t = i * period_s + (at >= 0 && i >= at ? jump_s : 0);
    std::snprintf(b, sizeof b, "%.6f,11.41174,%s\n", t, i == at && !cell.empty() ? cell.c_str() : p);
    s += b;
  }
  return s;
}

// A long file's columns are sized from its first chunk, not doubled chunk by chunk: 300 000 rows
// (five chunks) held capacity for 524 288 (1.75 x) to the end of a diagnosis.
TEST(MeasurementFile, ALongFileIsHeldWithoutGrowthSlack) {
  hil::test::TempDir dir;
  const std::size_t n = 300000;
  const auto f = dir.write("long.csv", "t_s,theta_cmd_deg,p_meas_mpa\n" + rows_with(static_cast<int>(n), 0.001));
  const auto m = hil::analysis::load_measurement(f);
  ASSERT_EQ(m.rows.size(), n);
  for (const auto* column : {&m.rows.t_s, &m.rows.theta_cmd_rad, &m.rows.p_meas_pa}) {
    EXPECT_GE(column->capacity(), n);
    EXPECT_LE(column->capacity(), n + n / 20) << "more than 5 % slack";
  }
  EXPECT_EQ(m.rows.theta_motor_rad.capacity(), 0u);  // absent columns take nothing
  EXPECT_EQ(m.rows.p_ref_pa.capacity(), 0u);
  EXPECT_DOUBLE_EQ(m.rows.t_s.back(), 299.999);  // every row, in order
}

// A time column that jumps or crawls: refused at the row where it happens, before any replay (a
// 1e9 s jump overflowed the replay's step count and was then accepted with a 96 % fit; a 1e6 s
// jump or a 10 s period ran diagnose for minutes).
TEST(MeasurementFile, TimeJumpsAndSlowLogsAreRefusedAtTheirLine) {
  hil::test::TempDir dir;
  const std::string head = "t_s,theta_cmd_deg,p_meas_mpa\n";  // data row i is on line i + 2
  for (const double jump_s : {1e6, 1e9, 6.0}) {
    const auto f = dir.write("jump.csv", head + rows_with(2000, 1e-3, 1000, "", jump_s));
    for (const std::string& e : {error_of([&] { load_measurement(f); }), error_of([&] { compare_file(nominal(), f); })}) {
      EXPECT_NE(e.find(f.string() + ":1002:1: column 't_s': a gap of"), std::string::npos) << jump_s << ": " << e;
    }
  }
  // A 10 s sample period: the second row is already a gap.
  auto f = dir.write("slow10.csv", head + rows_with(100, 10.0));
  EXPECT_NE(error_of([&] { load_measurement(f); }).find(f.string() + ":3:1: column 't_s': a gap of 10 s"), std::string::npos);
  // 0.1 s per row: no single gap, but the log outruns one row per 20 ms from row 63 on
  // (t = 6.3 s > 5 s + 63 * 20 ms).
  f = dir.write("slow01.csv", head + rows_with(200, 0.1));
  std::string e = error_of([&] { load_measurement(f); });
  EXPECT_NE(e.find(f.string() + ":65:1: column 't_s': the log covers 6.3 s in its first 64 rows"), std::string::npos) << e;
  // A dropout of 2 s in a 1 kHz log is a dropout, not two runs: accepted and replayed.
  f = dir.write("dropout.csv", head + rows_with(3000, 1e-3, 1500, "", 2.0));
  const auto r = compare_file(nominal(), f);
  EXPECT_TRUE(std::isfinite(r.fit_pct));
  EXPECT_TRUE(std::isfinite(r.error.rmse_pa));
}

// A raised cancel flag (a server shutting down) stops compare and diagnose before their next unit
// of work, and nothing is written; without it the same calls run to their outputs.
TEST(Cancel, CompareAndDiagnoseStopAndWriteNothing) {
  hil::test::TempDir dir;
  const auto f = dir.write("steady.csv", "t_s,theta_cmd_deg,p_meas_mpa\n" + rows(2000));
  const std::atomic<bool> raised{true}, lowered{false};
  hil::analysis::CompareOptions c;
  c.model_file = hil::test::nominal_model();
  c.data_file = f;
  c.quiet = true;
  c.out_dir = dir.path() / "cmp_cancelled";
  c.cancel = &raised;
  EXPECT_THROW(hil::analysis::run_compare(c), hil::analysis::Cancelled);
  EXPECT_FALSE(fs::exists(c.out_dir));
  hil::analysis::DiagnoseOptions d;
  d.model_file = hil::test::nominal_model();
  d.data_files = {f};
  d.quiet = true;
  d.out_dir = dir.path() / "diag_cancelled";
  d.settings.cancel = &raised;
  EXPECT_THROW(hil::analysis::run_diagnose(d), hil::analysis::Cancelled);
  EXPECT_FALSE(fs::exists(d.out_dir));
  c.out_dir = dir.path() / "cmp";
  c.cancel = &lowered;
  hil::analysis::run_compare(c);
  EXPECT_TRUE(fs::exists(c.out_dir / "compare.json"));
}

// The replay itself cannot be made to overflow or run away by a time stamp.
TEST(Replay, AStepBeyondTheLongestGapIsNaNNotAnOverflow) {
  const hil::plant::Plant quiet = hil::analysis::noise_free(nominal());
  hil::analysis::Replayer r(quiet);
  r.start({0.0, 1e6, hil::units::deg_to_rad(11.4), 1});
  EXPECT_TRUE(std::isfinite(r.advance(0.001, hil::units::deg_to_rad(11.4), hil::plant::kNaN)));
  EXPECT_TRUE(std::isnan(r.advance(1e9, hil::units::deg_to_rad(11.4), hil::plant::kNaN)));
  EXPECT_TRUE(std::isnan(r.advance(1e9, hil::units::deg_to_rad(11.4), hil::plant::kNaN)));  // not forward
}

// Pressure and angle columns that no rig can have written: refused naming file:line:column (they
// gave exit 0 with NaN metrics, and diagnose called some of them "explained").
TEST(MeasurementFile, NonsenseReadingsAreRefusedNamingFileLineAndColumn) {
  hil::test::TempDir dir;
  const std::string head = "t_s,theta_cmd_deg,p_meas_mpa\n";
  struct Case {
    std::string name, body, where, what;
  };
  std::string zero, constant, huge;
  for (int i = 0; i < 500; ++i) {
    char b[100];
    std::snprintf(b, sizeof b, "%.3f,11.4,0\n", i * 1e-3);
    zero += b;
    std::snprintf(b, sizeof b, "%.3f,11.4,1.2\n", i * 1e-3);
    constant += b;
    std::snprintf(b, sizeof b, "%.3f,11.4,%.6g\n", i * 1e-3, 1e300 * (1 + 1e-3 * std::sin(i)));
    huge += b;
  }
  const std::vector<Case> cases = {
      {"zero.csv", head + zero, ":2:3: column 'p_meas_mpa': ", "0 MPa on every row (lines 2-501)"},
      {"constant.csv", head + constant, ":2:3: column 'p_meas_mpa': ", "1.2 MPa on every row (lines 2-501)"},
      {"huge.csv", head + huge, ":2:3: column 'p_meas_mpa': ", "outside what a chamber-pressure transducer reads"},
      {"cell.csv", head + rows_with(500, 1e-3, 321, "1e308"), ":323:3: column 'p_meas_mpa': ", "1e+308 MPa is outside"},
      {"negative.csv", head + rows_with(500, 1e-3, 40, "-5"), ":42:3: column 'p_meas_mpa': ", "-5 MPa is outside"},
      {"cmd.csv",
       head +
           [] {
             std::string s = rows_with(500, 1e-3);
             return s.replace(s.find("11.41174", 30 * 20), 8, "1e300");
           }(),
       ":24:2: column 'theta_cmd_deg': ", "1e+300 deg is more than a turn"},
      {"motor.csv",
       "t_s,theta_cmd_deg,p_meas_mpa,theta_motor_deg\n" +
           [] {
             std::string s;
             for (int i = 0; i < 500; ++i) {
               char b[100];
               std::snprintf(b, sizeof b, "%.3f,11.4,%.6f,%s\n", i * 1e-3, 1 + 1e-3 * std::sin(i), i == 77 ? "-4000" : "11.4");
               s += b;
             }
             return s;
           }(),
       ":79:4: column 'theta_motor_deg': ", "-4000 deg is more than a turn"},
  };
  for (const Case& c : cases) {
    const auto f = dir.write(c.name, c.body);
    for (const std::string& e : {error_of([&] { load_measurement(f); }), error_of([&] { compare_file(nominal(), f); })}) {
      EXPECT_NE(e.find(f.string() + c.where), std::string::npos) << c.name << ": " << e;
      EXPECT_NE(e.find(c.what), std::string::npos) << c.name << ": " << e;
    }
  }
}

TEST(MeasurementFile, BadModelFileIsALocatedConfigError) {
  hil::test::TempDir dir;
  const auto model = dir.write("m.yaml", "effects:\n  motor_servo: {time_constant_s: -1, rate_limit_deg_s: 60}\n");
  const auto data = dir.write("d.csv", "t_s,theta_cmd_deg,p_meas_mpa\n" + rows(60));
  hil::analysis::CompareOptions o{
      .model_file = model, .data_file = data, .out_dir = dir.path() / "out", .dialect = {}, .progress = false, .quiet = true};
  const std::string e = error_of([&] { hil::analysis::run_compare(o); });
  EXPECT_NE(e.find("m.yaml:2:"), std::string::npos) << e;
  EXPECT_NE(e.find("time_constant_s"), std::string::npos) << e;
}

// --- statistics -----------------------------------------------------------------------------

TEST(Statistics, NoiseFromSecondDifferencesIgnoresTheSignal) {
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0, 2000);
  std::vector<double> y(60000);
  for (std::size_t k = 0; k < y.size(); ++k) {
    const double t = k * 1e-3;
    y[k] = 1.2e6 + 2e5 * std::sin(2 * std::numbers::pi * 0.3 * t) + (std::fmod(t, 5) < 2.5 ? 1e5 : 0) + noise(rng);
  }
  EXPECT_NEAR(hil::analysis::noise_sigma_from_data(y), 2000, 60);
}

// Feeds a residual of known shape through the analyzer (drive: a triangle, reversing every 2 s).
hil::analysis::ResidualReport analyze(const std::function<double(double t, double drive_deg)>& residual, double noise_pa,
                                      std::size_t n = 40000) {
  hil::analysis::AnalyzerOptions o;
  o.expected_rows = n;
  o.expected_duration_s = n * 1e-3;
  hil::analysis::ResidualAnalyzer an(o);
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0, noise_pa);
  for (std::size_t k = 0; k < n; ++k) {
    const double t = k * 1e-3;
    const double phase = std::fmod(t, 4.0);
    const double drive_deg = 10 + (phase < 2 ? phase : 4 - phase);
    const double model = 1.2e6 + 1e5 * std::sin(0.5 * t);
    const double y = model + residual(t, drive_deg) + noise(rng);
    an.add({t, y, model, drive_deg * std::numbers::pi / 180, NAN, 0.0});
  }
  return an.finish();
}

const hil::analysis::Regime& regime(const hil::analysis::ResidualReport& r, const std::string& name) {
  for (const auto& g : r.regimes)
    if (g.name == name) return g;
  throw std::runtime_error("no regime " + name);
}

TEST(Statistics, WhiteResidualIsWhiteAndAtTheFloor) {
  const auto r = analyze([](double, double) { return 0.0; }, 2000);
  EXPECT_TRUE(r.diagnostics.white);
  EXPECT_FALSE(r.diagnostics.input_correlated);
  EXPECT_NEAR(r.noise_sigma_pa, 2000, 80);
  EXPECT_NEAR(r.fit_pct, r.noise_floor_fit_pct, 0.3);
  EXPECT_NEAR(r.diagnostics.tau_int_samples, 1.0, 0.2);
  EXPECT_TRUE(r.diagnostics.peaks.empty());
}

// An AR(1) series e[k] = phi e[k-1] + w[k].
std::vector<double> ar1(double phi, std::size_t n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> w(0, 1);
  std::vector<double> e(n);
  double x = 0;
  for (auto& v : e) v = x = phi * x + w(rng);
  return e;
}

TEST(Statistics, AutocorrelationTimeOfAnAr1IsItsClosedForm) {
  // tau_int = 1 + 2 sum phi^l = (1 + phi) / (1 - phi): 9 for phi = 0.8, 1 for white noise.
  EXPECT_NEAR(hil::analysis::integrated_autocorrelation_time(ar1(0.8, 300000, 5)), 9.0, 0.45);
  EXPECT_NEAR(hil::analysis::integrated_autocorrelation_time(ar1(0.0, 300000, 6)), 1.0, 0.1);
}

TEST(Statistics, AutocorrelationTimeIsTheDirectSumOfTheLaggedProducts) {
  // The FFT's result against the definition, lag by lag: rho(l) = sum (e_i - m)(e_{i+l} - m) /
  // sum (e_i - m)^2 for l <= 2000, summed in pairs until a pair is not positive (Geyer). Series
  // just below a power of two (an FFT padded too little wraps their lags around) and just above.
  for (const std::size_t n : {std::size_t{2100}, std::size_t{4000}, std::size_t{4097}, std::size_t{65000}}) {
    const std::vector<double> e = ar1(0.999, n, static_cast<unsigned>(n));  // correlated for long: Geyer runs far
    double m = 0;
    for (double v : e) m += v;
    m /= static_cast<double>(n);
    const std::size_t lags = std::min<std::size_t>(2000, n - 1);
    std::vector<double> rho(lags + 1);
    for (std::size_t l = 0; l <= lags; ++l) {
      double sum = 0;
      for (std::size_t i = 0; i + l < n; ++i) sum += (e[i] - m) * (e[i + l] - m);
      rho[l] = sum;
    }
    for (std::size_t l = lags + 1; l-- > 0;) rho[l] /= rho[0];
    double pairs = 0;
    for (std::size_t k = 0; 2 * k + 1 < rho.size() && rho[2 * k] + rho[2 * k + 1] > 0; ++k) pairs += rho[2 * k] + rho[2 * k + 1];
    const double direct = std::max(1.0, 2 * pairs - 1);
    EXPECT_NEAR(hil::analysis::integrated_autocorrelation_time(e), direct, 1e-9 * direct) << n << " samples";
  }
}

TEST(Statistics, FitPercentIsTheDefinition) {
  // fit = 100 (1 - |e| / |y - mean y|): a constant residual of half the spread gives 50 %.
  const auto r0 = analyze([](double, double) { return 0.0; }, 0.0);
  const auto r = analyze([&](double, double) { return 0.5 * r0.y_spread_pa; }, 0.0);
  EXPECT_NEAR(r.fit_pct, 50.0, 1e-6);
  EXPECT_NEAR(r.error.bias_pa, 0.5 * r0.y_spread_pa, 1e-6);
  EXPECT_NEAR(r.error.rmse_pa, 0.5 * r0.y_spread_pa, 1e-6);
}

TEST(Statistics, ErrorAfterReversalsIsLocalisedAndCorrelatedWithTheInput) {
  // 30 kPa for 0.3 s after each reversal of the drive (at 2, 4, 6, ... s).
  const auto r = analyze(
      [](double t, double) {
        const double since = std::fmod(t, 2.0);
        return t > 1 && since < 0.3 ? 3e4 : 0.0;
      },
      2000);
  EXPECT_GT(regime(r, "after_reversal").error.rmse_pa, 2 * r.error.rmse_pa);
  EXPECT_LT(regime(r, "holding").error.samples, r.rows / 10);  // the drive never holds
  EXPECT_GE(r.reversals, 18u);
  EXPECT_FALSE(r.diagnostics.white);
  // The worst windows all start within 0.3 s after a reversal.
  ASSERT_FALSE(r.worst.empty());
  for (std::size_t i : r.worst) EXPECT_LT(std::fmod(r.windows[i].t0_s, 2.0), 0.35) << r.windows[i].t0_s;
  ASSERT_FALSE(r.failing.empty());
  // The spectrum's peaks are harmonics of the motion cycle (reversal every 2 s: 0.25 Hz).
  ASSERT_FALSE(r.diagnostics.peaks.empty());
  EXPECT_NE(r.diagnostics.peaks[0].name.find("motion cycle"), std::string::npos) << r.diagnostics.peaks[0].name;
  // Event-locked: the mean residual just after a reversal is the 30 kPa step.
  EXPECT_NEAR(r.diagnostics.after_opening_mean_pa[5], 3e4, 3e3);
}

TEST(Statistics, PeriodicDisturbanceIsNamedInTheSpectrum) {
  const auto r = analyze([](double t, double) { return 1e4 * std::sin(2 * std::numbers::pi * 7.3 * t); }, 2000);
  ASSERT_FALSE(r.diagnostics.peaks.empty());
  EXPECT_NEAR(r.diagnostics.peaks[0].hz, 7.3, 0.3);
  EXPECT_GT(r.diagnostics.peaks[0].power_share, 0.8);
  EXPECT_NE(r.diagnostics.peaks[0].name.find("periodic component at 7.3"), std::string::npos) << r.diagnostics.peaks[0].name;
  const auto mains = analyze([](double t, double) { return 5e3 * std::sin(2 * std::numbers::pi * 50 * t); }, 2000);
  ASSERT_FALSE(mains.diagnostics.peaks.empty());
  EXPECT_NE(mains.diagnostics.peaks[0].name.find("mains"), std::string::npos) << mains.diagnostics.peaks[0].name;
}

TEST(Statistics, DriftShowsAsLateAndSlow) {
  const auto r = analyze([](double t, double) { return 1.5e3 * t; }, 2000);
  EXPECT_GT(regime(r, "late").error.rmse_pa, 2 * regime(r, "early").error.rmse_pa);
  EXPECT_GT(r.diagnostics.low_frequency_share, 0.8);
  bool grows = false;
  for (const auto& line : r.signature) grows |= line.find("Grows over the run") != std::string::npos;
  EXPECT_TRUE(grows);
}

// An error that lives in one span of the run: the signature says where, the change points are
// its edges (within a window), and it does not call it "spread evenly over the regimes".
TEST(Statistics, ATimeConfinedErrorIsNamedWithItsSpan) {
  const auto r = analyze([](double t, double) { return t >= 12 && t < 18 ? 1.5e4 + 5e3 * std::sin(3 * t) : 0.0; }, 2000);
  std::string sig;
  for (const auto& line : r.signature) sig += line + " ";
  EXPECT_NE(sig.find("The error is confined to 12"), std::string::npos) << sig;
  EXPECT_NE(sig.find("recovered at 18"), std::string::npos) << sig;
  EXPECT_EQ(sig.find("Spread evenly"), std::string::npos) << sig;
  ASSERT_GE(r.change_points_s.size(), 2u) << sig;
  EXPECT_NEAR(r.change_points_s.front(), 12.0, r.window_width_s + 1e-9);
  EXPECT_NEAR(r.change_points_s.back(), 18.0, r.window_width_s + 1e-9);
  EXPECT_TRUE(r.segments.front().at_floor);
  EXPECT_TRUE(r.segments.back().at_floor);
  for (std::size_t i = 1; i + 1 < r.segments.size(); ++i) EXPECT_FALSE(r.segments[i].at_floor);
  // A change that does not recover.
  const auto late = analyze([](double t, double) { return t >= 25 ? 1e4 : 0.0; }, 2000);
  sig.clear();
  for (const auto& line : late.signature) sig += line + " ";
  EXPECT_NE(sig.find("The error starts at 25"), std::string::npos) << sig;
  EXPECT_NE(sig.find("did not recover"), std::string::npos) << sig;
  // The other side: an error everywhere (after every reversal) and pure noise have no span.
  for (const auto& other : {analyze([](double t, double) { return std::fmod(t, 2.0) < 0.3 ? 3e4 : 0.0; }, 2000),
                            analyze([](double, double) { return 0.0; }, 2000)}) {
    for (const auto& line : other.signature) {
      EXPECT_EQ(line.find("confined"), std::string::npos) << line;
      EXPECT_EQ(line.find("The error starts"), std::string::npos) << line;
      EXPECT_EQ(line.find("comes and goes"), std::string::npos) << line;
    }
  }
  EXPECT_TRUE(analyze([](double, double) { return 0.0; }, 2000).change_points_s.empty());
}

// A reading in ADC steps q: a perfect model leaves the noise plus the quantisation error, sigma^2 +
// q^2/12, and the estimate must say so (the plain median sat on a multiple of q: 1.8 kPa for 2 kPa
// noise in 1 kPa steps, so a fit at the floor was called partly explained). Steps from 0.5 to 2
// sigma; the same estimate for logs at 200 Hz and 5 kHz of a chamber with its 0.1 s dynamics.
TEST(Statistics, NoiseEstimateHoldsForQuantisedReadingsAndOtherRates) {
  for (const double rate_hz : {200.0, 1000.0, 5000.0}) {
    for (const double step_per_sigma : {0.0, 0.5, 1.0, 2.0}) {
      const double sigma_pa = 2000, q_pa = step_per_sigma * sigma_pa;
      std::mt19937 rng(11);
      std::normal_distribution<double> noise(0, sigma_pa);
      std::vector<double> y;
      double p = 1.0e6;
      const double dt = 1 / rate_hz;
      for (double t = 0; t < 30; t += dt) {
        const double target = std::fmod(t, 5) < 2.5 ? 1.0e6 : 1.5e6;  // steps every 2.5 s, tau 0.1 s
        p += (target - p) * (1 - std::exp(-dt / 0.1));
        const double v = p + noise(rng);
        y.push_back(q_pa > 0 ? q_pa * std::round(v / q_pa) : v);
      }
      const double expected = std::sqrt(sigma_pa * sigma_pa + q_pa * q_pa / 12);
      EXPECT_NEAR(hil::analysis::noise_sigma_from_data(y), expected, 0.04 * expected)
          << rate_hz << " Hz, step " << step_per_sigma << " sigma";
    }
  }
}

TEST(Statistics, CoarselyQuantisedReadingsStillHaveANoiseEstimate) {
  hil::analysis::ResidualAnalyzer an({});
  std::mt19937 rng(9);
  std::normal_distribution<double> noise(0, 300);
  for (int k = 0; k < 20000; ++k) {
    const double t = k * 1e-3, model = 1.2e6 + 1e5 * std::sin(0.5 * t);
    const double y = 1e3 * std::round((model + noise(rng)) / 1e3);  // a 1 kPa ADC step
    an.add({t, y, model, 0.2, NAN, 0.0});
  }
  const auto r = an.finish();
  EXPECT_GT(r.noise_sigma_pa, 100);
  EXPECT_LT(r.noise_sigma_pa, 600);
  EXPECT_TRUE(std::isfinite(r.noise_floor_fit_pct));
}

// --- replay ---------------------------------------------------------------------------------

TEST(Replay, DecimationKeepsTheCommandIntegral) {
  hil::analysis::ReplayData d;
  for (int k = 0; k < 101; ++k) {
    d.t_s.push_back(k * 1e-3 * (k % 2 ? 1.2 : 1.0));
    d.cmd_held_rad.push_back(std::sin(k * 0.1));
    d.y_pa.push_back(1e6);
  }
  for (std::size_t k = 1; k < d.t_s.size(); ++k) d.t_s[k] = d.t_s[k - 1] + (k % 2 ? 1.2e-3 : 0.8e-3);
  const auto c = hil::analysis::decimate(d, 4);
  double full = 0, dec = 0;
  for (std::size_t k = 1; k <= 100; ++k) full += d.cmd_held_rad[k] * (d.t_s[k] - d.t_s[k - 1]);
  for (std::size_t j = 1; j < c.size(); ++j) dec += c.cmd_held_rad[j] * (c.t_s[j] - c.t_s[j - 1]);
  EXPECT_NEAR(dec, full, 1e-12);
  EXPECT_EQ(c.size(), 26u);
}

// Several files of one rig: each segment is replayed from its own start on its own clock, exactly
// as the file alone (diagnose --data a --data b).
TEST(Replay, SegmentsReplayAsTheirFilesAlone) {
  hil::test::TempDir dir;
  std::vector<hil::analysis::Measurement> files;
  for (int i = 0; i < 2; ++i) {
    hil::test::LabLog log;
    log.name = "seg" + std::to_string(i);
    log.t0_s = 50.0 + 400.0 * i;  // other clocks: the model's time starts at each file's first row
    log.duration_s = 3;
    log.seed = 31 + static_cast<std::uint64_t>(i);
    log.truth = [](const hil::plant::Plant& p) { return hil::test::with_block(p, "throat_erosion", "rate_mm2_per_s: 2"); };
    files.push_back(hil::analysis::load_measurement(hil::test::make_lab_log(log, dir.path())));
  }
  // Erosion is time-dependent: a model whose clock ran on across the files would differ.
  const auto model = hil::analysis::noise_free(hil::test::with_block(nominal(), "throat_erosion", "rate_mm2_per_s: 2"));
  const auto both = hil::analysis::replay_data({&files[0], &files[1]});
  ASSERT_EQ(both.segments.size(), 2u);
  ASSERT_EQ(both.size(), files[0].rows.size() + files[1].rows.size());
  std::vector<double> yhat(both.size());
  ASSERT_TRUE(hil::analysis::replay(model, both, yhat));
  std::size_t at = 0;
  for (const auto& f : files) {
    const auto one = hil::analysis::replay_data(f);
    std::vector<double> alone(one.size());
    ASSERT_TRUE(hil::analysis::replay(model, one, alone));
    for (std::size_t k = 0; k < alone.size(); ++k) ASSERT_EQ(yhat[at + k], alone[k]) << "row " << k;
    at += alone.size();
  }
  // Decimated, each segment keeps its first row and its start.
  const auto c = hil::analysis::decimate(both, 7);
  ASSERT_EQ(c.segments.size(), 2u);
  EXPECT_EQ(c.t_s[c.segment_begin(1)], files[1].rows.t_s[0]);
  EXPECT_EQ(c.segments[1].start.t0_s, files[1].rows.t_s[0]);
  // Files with and without the encoder are not replayed together.
  hil::test::LabLog enc;
  enc.name = "enc";
  enc.duration_s = 1;
  enc.encoder = true;
  const auto with_encoder = hil::analysis::load_measurement(hil::test::make_lab_log(enc, dir.path()));
  EXPECT_THROW(hil::analysis::replay_data({&files[0], &with_encoder}), std::invalid_argument);
}

// Writes and runs a small campaign with `hilbench sim`'s code path; returns the run's telemetry.
fs::path sim_telemetry(const fs::path& dir, const std::string& plant_file, double duration_s) {
  const std::string yaml = "name: roundtrip\nplant: " + plant_file + "\nduration_s: " + std::to_string(duration_s) +
                           "\nperiod_ms: 1\nseed: 42\nsensor_noise_kpa: 1.5\nreference:\n" +
                           hil::test::reference_random(8, 0.9, 1.5, 1.0, 3.0) +
                           "controller:\n  observer: robust\nruns:\n  - name: run\n    compensation: adaptive\n";
  const auto file = dir / "roundtrip.yaml";
  std::ofstream(file) << yaml;
  const auto campaign = hil::bench::load_campaign(file);
  hil::bench::SimOptions o;
  o.out_dir = dir / "runs";
  o.progress = false;
  hil::bench::run_campaign(campaign, o);
  return dir / "runs/roundtrip/run/telemetry.csv";
}

TEST(Replay, BenchTelemetryRoundTripsAtTheNoiseFloor) {
  hil::test::TempDir dir;
  const auto telemetry = sim_telemetry(dir.path(), hil::test::nominal_model().string(), 20);
  const auto j = hil::test::run_compare(hil::test::nominal_model(), telemetry, dir.path() / "cmp");
  EXPECT_GE(j.at("fit_pct").get<double>(), j.at("noise_floor_fit_pct").get<double>() - 0.1);
  EXPECT_NEAR(j.at("noise_sigma_kpa").get<double>(), 1.5, 0.1);
  EXPECT_LT(j.at("rmse_kpa").get<double>(), 1.6);
  EXPECT_TRUE(j.at("encoder").get<bool>());
  std::printf("[ round trip ] fit %.3f %% (noise floor %.3f %%), RMSE %.3f kPa\n", j.at("fit_pct").get<double>(),
              j.at("noise_floor_fit_pct").get<double>(), j.at("rmse_kpa").get<double>());
}

TEST(Replay, StreamedAndInMemoryAgree) {
  hil::test::TempDir dir;
  hil::test::Scenario s;
  s.name = "agree";
  s.duration_s = 12;
  s.reference_yaml = hil::test::reference_square(1.0, 1.4, 2.0);
  s.truth = [](const hil::plant::Plant& p) { return hil::test::with_block(p, "valve_offset", "offset_deg: 0.7"); };
  const auto f = hil::test::make_measurement(s, dir.path());
  const auto a = compare_file(nominal(), f);
  const auto b = hil::analysis::compare_measurement(nominal(), load_measurement(f));
  EXPECT_DOUBLE_EQ(a.fit_pct, b.fit_pct);
  EXPECT_DOUBLE_EQ(a.rss_pa2, b.rss_pa2);
  EXPECT_EQ(a.rows, 12000u);
}

TEST(Replay, WithAnEncoderTheDriveIsCheckedSeparately) {
  // A transport delay with the encoder logged: invisible to the pressure replay (which uses the
  // encoder), so compare is at the floor, diagnose names nothing, and both say where it shows.
  hil::test::TempDir dir;
  hil::test::Scenario s;
  s.name = "delay_with_encoder";
  s.duration_s = 15;
  s.seed = 120;
  s.reference_yaml = hil::test::reference_square(1.0, 1.4, 2.5);
  s.truth = [](const hil::plant::Plant& p) { return hil::test::with_block(p, "transport_delay", "delay_s: 0.03"); };
  const auto data = hil::test::make_measurement(s, dir.path());
  const auto c = hil::test::run_compare(hil::test::nominal_model(), data, dir.path() / "cmp");
  EXPECT_GE(c.at("fit_pct").get<double>(), c.at("noise_floor_fit_pct").get<double>() - 0.2);
  ASSERT_TRUE(c.contains("motor_channel"));
  EXPECT_FALSE(c.at("motor_channel").at("matches").get<bool>());
  EXPECT_GT(c.at("motor_channel").at("rmse_deg").get<double>(), 0.05);
  const auto d = hil::test::run_diagnose(hil::test::nominal_model(), data, dir.path() / "diag");
  EXPECT_EQ(d.at("verdict"), "nothing_missing");
  ASSERT_EQ(d.at("not_identifiable").size(), 2u);
  for (const auto& n : d.at("not_identifiable")) {
    EXPECT_NE(n.at("reason").get<std::string>().find("misses the encoder"), std::string::npos) << n;
  }
  // Without the delay the drive model follows the encoder.
  s.name = "nominal_with_encoder";
  s.truth = [](const hil::plant::Plant& p) { return p; };
  const auto c2 =
      hil::test::run_compare(hil::test::nominal_model(), hil::test::make_measurement(s, dir.path()), dir.path() / "cmp2");
  EXPECT_TRUE(c2.at("motor_channel").at("matches").get<bool>()) << c2.at("motor_channel");
}

// A copy of a measurement file with its pressure column (MPa) changed row by row: f(row, t_s,
// p_mpa) returns the new value, or NaN to drop the row.
fs::path with_pressure(const fs::path& file, const fs::path& out, const std::function<double(std::size_t, double, double)>& f) {
  std::ifstream in(file);
  std::ofstream o(out);
  std::string line;
  std::vector<std::string> header;
  std::size_t p_col = 0, t_col = 0, row = 0;
  const auto split = [](const std::string& l) {
    std::vector<std::string> cells;
    std::stringstream ss(l);
    for (std::string c; std::getline(ss, c, ',');) cells.push_back(c);
    return cells;
  };
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#' || header.empty()) {
      if (!line.empty() && line[0] != '#') {
        header = split(line);
        p_col = static_cast<std::size_t>(std::find(header.begin(), header.end(), "p_meas_mpa") - header.begin());
        t_col = static_cast<std::size_t>(std::find(header.begin(), header.end(), "t_s") - header.begin());
      }
      o << line << '\n';
      continue;
    }
    auto cells = split(line);
    const double p = f(row++, std::stod(cells[t_col]), std::stod(cells[p_col]));
    if (std::isnan(p)) continue;
    char b[32];
    std::snprintf(b, sizeof b, "%.6f", p);
    cells[p_col] = b;
    for (std::size_t i = 0; i < cells.size(); ++i) o << (i ? "," : "") << cells[i];
    o << '\n';
  }
  return out;
}

// Every m-th data row of a measurement file (metadata and header kept): a logger at a lower rate.
fs::path every_mth_row(const fs::path& file, std::size_t m, const fs::path& out) {
  return with_pressure(file, out, [m](std::size_t k, double, double p) { return k % m == 0 ? p : hil::plant::kNaN; });
}

TEST(Replay, ACoarseLogIsReplayedWithoutAMadeUpLag) {
  // A logger at 100 Hz on a 1 kHz bench: held over a 10 ms step, the row's command came 5 ms late
  // and the encoder's end angle moved the valve 5 ms early. The replay took that for a sensor lag:
  // 8.5 ms "found" on a plant without one, a real 20 ms lag fitted as 28.8 +- 0.2 ms. (The
  // integral controller's command is smooth; a compensator's jumps and boosts between the rows are
  // lost to a log this coarse whatever the replay does.)
  hil::test::TempDir dir;
  hil::test::Scenario s;
  s.compensation = "none";
  s.duration_s = 20;
  s.seed = 31;
  s.reference_yaml = hil::test::reference_random(5, 0.9, 1.6, 0.6, 1.5);
  for (const bool encoder : {true, false}) {
    s.name = encoder ? "nominal" : "nominal_no_encoder";
    s.encoder = encoder;
    const auto log_100hz = every_mth_row(hil::test::make_measurement(s, dir.path()), 10, dir.path() / (s.name + "_100hz.csv"));
    const auto c = hil::test::run_compare(hil::test::nominal_model(), log_100hz, dir.path() / ("cmp_" + s.name));
    EXPECT_GE(c.at("fit_pct").get<double>(), c.at("noise_floor_fit_pct").get<double>() - 0.1) << s.name;
    const auto d = hil::test::run_diagnose(hil::test::nominal_model(), log_100hz, dir.path() / ("diag_" + s.name));
    EXPECT_EQ(d.at("verdict"), "nothing_missing") << s.name << ": " << d.at("summary");
  }
  // With the encoder a lag of the pressure reading is told from one of the drive.
  s.name = "lag";
  s.encoder = true;
  s.truth = [](const hil::plant::Plant& p) { return hil::test::with_block(p, "sensor_lag", "time_constant_s: 0.02"); };
  const auto lag_100hz = every_mth_row(hil::test::make_measurement(s, dir.path()), 10, dir.path() / "lag_100hz.csv");
  const auto d = hil::test::run_diagnose(hil::test::nominal_model(), lag_100hz, dir.path() / "diag_lag");
  ASSERT_EQ(d.at("added").size(), 1u) << d.at("summary");
  EXPECT_EQ(d.at("added")[0].at("effect"), "sensor_lag");
  EXPECT_NEAR(hil::test::param(d.at("added")[0], "time_constant_s"), 0.02, 0.001);
}

std::string log_warnings_of(const nlohmann::json& compare_json) {
  std::string all;
  for (const auto& w : compare_json.at("log_warnings")) all += w.get<std::string>() + "\n";
  return all;
}

TEST(CompareLog, WhatTheFileItselfShowsIsSaidFirst) {
  // A logger's damage that a replay cannot undo, each on an otherwise clean log of the nominal
  // plant. Before, each was fitted as physics: a pressure updated at 100 Hz and logged at 1 kHz
  // as a 5 ms sensor lag and "mains hum", a 3 s dropout as "something changed at 9.75 s", a
  // clipped transducer as a burn-rate exponent of 0.28, a file in bar as a burn rate at the end
  // of its search range. None of them was said.
  hil::test::TempDir dir;
  hil::test::Scenario s;
  s.name = "clean";
  s.compensation = "none";
  s.encoder = false;
  s.duration_s = 20;
  s.seed = 17;
  s.reference_yaml = hil::test::reference_random(6, 0.9, 1.6, 0.6, 1.5);
  const auto clean = hil::test::make_measurement(s, dir.path());
  const auto model = hil::test::nominal_model();
  const auto compare = [&](const fs::path& data) {
    return log_warnings_of(hil::test::run_compare(model, data, dir.path() / ("cmp_" + data.stem().string())));
  };
  EXPECT_EQ(compare(clean), "");

  double held = 0;
  const auto stale = with_pressure(clean, dir.path() / "stale.csv", [&](std::size_t k, double, double p) {
    if (k % 10 == 0) held = p;  // a reading updated every 10 ms, logged every 1 ms
    return held;
  });
  const std::string w_stale = compare(stale);
  EXPECT_NE(w_stale.find("repeat the pressure of the row before, in runs of about 10 rows"), std::string::npos) << w_stale;
  const auto d = hil::test::run_diagnose(model, stale, dir.path() / "diag_stale");
  ASSERT_FALSE(d.at("summary").empty());
  EXPECT_EQ(d.at("summary")[0].get<std::string>().rfind("Log: ", 0), 0u) << d.at("summary");
  EXPECT_EQ(d.at("log_warnings").size(), 1u);

  const auto holed = with_pressure(clean, dir.path() / "hole.csv",
                                   [](std::size_t, double t, double p) { return t >= 10 && t < 13 ? hil::plant::kNaN : p; });
  const std::string w_hole = compare(holed);
  EXPECT_NE(w_hole.find("1 hole in the log (3 s at 10 s"), std::string::npos) << w_hole;

  const auto clipped =
      with_pressure(clean, dir.path() / "clip.csv", [](std::size_t, double, double p) { return std::min(p, 1.45); });
  const std::string w_clip = compare(clipped);
  EXPECT_NE(w_clip.find("read exactly 1.45 MPa, the file's highest reading"), std::string::npos) << w_clip;

  const auto bar = with_pressure(clean, dir.path() / "bar.csv", [](std::size_t, double, double p) { return 10 * p; });
  const std::string w_bar = compare(bar);
  EXPECT_NE(w_bar.find("far above what the model makes at any valve angle"), std::string::npos) << w_bar;
}

TEST(DiagnoseText, AValueAtTheEndOfItsSearchRangeIsNotGivenAsAMeasurement) {
  // A file logged in bar: the burn rate fitted to 10 mm/s, the top of its 2.5..10 range, was
  // printed "10 +- 1.4" like any finding.
  hil::analysis::FittedParam p;
  p.key = "burn_rate_mm_s_at_1mpa";
  p.search_lo = 2.5;
  p.search_hi = 10;
  p.sigma = 1.4;
  for (const double v : {10.0, 9.995, 2.5, 2.504}) {
    p.value = v;
    EXPECT_TRUE(p.at_search_limit()) << v;
    EXPECT_NE(p.limit_text().find("at the end of its search range, 2.5 to 10"), std::string::npos) << v;
  }
  for (const double v : {5.0, 9.98, 2.52}) {
    p.value = v;
    EXPECT_FALSE(p.at_search_limit()) << v;
    EXPECT_EQ(p.limit_text(), "") << v;
  }
  p.search_lo = p.search_hi = std::numeric_limits<double>::quiet_NaN();  // a grid parameter: no range
  p.value = 10;
  EXPECT_FALSE(p.at_search_limit());
}

TEST(Replay, CandidatesAreTheBuiltInEightPlusUserEffects) {
  const auto names = hil::analysis::builtin_candidate_names();
  EXPECT_EQ(names, (std::vector<std::string>{"backlash_change", "valve_offset", "throat_erosion", "sensor_lag", "transport_delay",
                                             "sensor_bias", "motor_dynamics", "burn_rate"}));
  const auto all = hil::analysis::candidates_for(hil::analysis::noise_free(nominal()));
  EXPECT_EQ(all.size(), names.size());  // this test binary registers no user effect
  EXPECT_THROW(hil::analysis::candidates_for(nominal(), {"valve_ofset"}), std::invalid_argument);
}

// --- the command line -----------------------------------------------------------------------

struct CliRun {
  int code;
  std::string out;
};
CliRun hilbench(const std::string& args) {
  const std::string cmd = std::string(HIL_BINARY_DIR) + "/bench/hilbench " + args + " 2>&1";
  std::FILE* p = popen(cmd.c_str(), "r");
  std::string out;
  char buf[4096];
  while (std::fgets(buf, sizeof buf, p)) out += buf;
  const int status = pclose(p);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

TEST(CommandLine, UsageAndBadFiles) {
  hil::test::TempDir dir;
  const std::string model = hil::test::nominal_model().string();
  CliRun r = hilbench("compare --model " + model);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("--data FILE.csv is required"), std::string::npos) << r.out;
  r = hilbench("diagnose --data x.csv --modle m.yaml");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("did you mean --model"), std::string::npos) << r.out;
  const auto bad = dir.write("bad.csv", "t_s,theta_cmd_deg,p_meas_mpa\n" + rows(5) + "0.005,1..2,1.0\n");
  for (const char* cmd : {"compare", "diagnose"}) {
    r = hilbench(std::string(cmd) + " --model " + model + " --data " + bad.string() + " --out " + (dir.path() / "o").string());
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_NE(r.out.find(bad.string() + ":7:2: column 'theta_cmd_deg': not a number: '1..2'"), std::string::npos) << r.out;
  }
  const auto empty = dir.write("empty.csv", "");
  r = hilbench("compare --model " + model + " --data " + empty.string());
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("empty.csv:1:1"), std::string::npos) << r.out;
}

// diagnose on files no rig can have written: exit 1 with the place, never a verdict (it called a
// constant and a 1e300 pressure "explained" and accepted a 1e9 s time jump with a 96 % fit).
TEST(CommandLine, DiagnoseRefusesNonsenseFilesWithTheirPlace) {
  hil::test::TempDir dir;
  const std::string model = hil::test::nominal_model().string(), head = "t_s,theta_cmd_deg,p_meas_mpa\n";
  std::string constant;
  for (int i = 0; i < 300; ++i) constant += std::to_string(i * 1e-3) + ",11.4,1.2\n";
  const std::vector<std::pair<fs::path, std::string>> files = {
      {dir.write("constant.csv", head + constant), ":2:3: column 'p_meas_mpa': the reading is 1.2 MPa on every row"},
      {dir.write("cell.csv", head + rows_with(300, 1e-3, 100, "1e308")), ":102:3: column 'p_meas_mpa': 1e+308 MPa"},
      {dir.write("jump.csv", head + rows_with(300, 1e-3, 150, "", 1e9)), ":152:1: column 't_s': a gap of"},
  };
  for (const auto& [file, what] : files) {
    const CliRun r = hilbench("diagnose --model " + model + " --data " + file.string() + " --out " + (dir.path() / "o").string());
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_NE(r.out.find(file.string() + what), std::string::npos) << r.out;
    EXPECT_EQ(r.out.find("explained"), std::string::npos) << r.out;
  }
}

// diagnose --data a --data b: files of one rig together; files that cannot be replayed the same way
// are refused with what is wrong.
TEST(CommandLine, DiagnoseTakesSeveralFilesOfOneRig) {
  hil::test::TempDir dir;
  const std::string model = hil::test::nominal_model().string(), out = (dir.path() / "d").string();
  std::vector<std::string> files;
  for (int i = 0; i < 2; ++i) {
    hil::test::LabLog log;
    log.name = "rig" + std::to_string(i);
    log.duration_s = 4;
    log.seed = 41 + static_cast<std::uint64_t>(i);
    log.noise_kpa = 2;
    files.push_back(hil::test::make_lab_log(log, dir.path()).string());
  }
  CliRun r = hilbench("diagnose --model " + model + " --data " + files[0] + " --data " + files[1] + " --out " + out + " --quiet");
  ASSERT_EQ(r.code, 0) << r.out;
  const auto d = hil::test::read_json(dir.path() / "d/diagnosis.json");
  EXPECT_EQ(d.at("verdict"), "nothing_missing");
  ASSERT_EQ(d.at("files").size(), 2u);
  EXPECT_EQ(d.at("files")[1].at("data_file"), files[1]);
  EXPECT_EQ(d.at("rows").get<std::size_t>(),
            d.at("files")[0].at("rows").get<std::size_t>() + d.at("files")[1].at("rows").get<std::size_t>());
  hil::test::LabLog enc;
  enc.name = "with_encoder";
  enc.duration_s = 2;
  enc.encoder = true;
  const std::string encoder_file = hil::test::make_lab_log(enc, dir.path()).string();
  r = hilbench("diagnose --model " + model + " --data " + files[0] + " --data " + encoder_file + " --out " + out);
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find(encoder_file + ": has theta_motor_deg column, but " + files[0] + " has none"), std::string::npos) << r.out;
}

// A logger on the Unix-epoch clock: compare's sentences name instants to the tenth of a second,
// not "1.76e+09 s" for every one of them (the JSON always had the digits).
TEST(CommandLine, InstantsOfAnEpochClockKeepTheirDigits) {
  hil::test::TempDir dir;
  hil::test::LabLog log;
  log.name = "epoch";
  log.t0_s = 1764250000.0;
  log.duration_s = 4;
  log.truth = [](const hil::plant::Plant& p) { return hil::test::with_block(p, "sensor_bias", "offset_kpa: 40"); };
  const std::string file = hil::test::make_lab_log(log, dir.path()).string();
  const CliRun r = hilbench("compare --model " + hil::test::nominal_model().string() + " --data " + file + " --out " +
                            (dir.path() / "c").string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(r.out.find("e+09"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(" at 176425000"), std::string::npos) << r.out;  // "max ... at 1764250001.2 s"
  EXPECT_NE(r.out.find("worst windows: 176425000"), std::string::npos) << r.out;
}

// --write-model that would overwrite an input (the data, the model, through another name) or is
// a folder is refused before the fit, and every input is left as it was.
TEST(CommandLine, DiagnoseRefusesAFittedModelPathThatIsAnInputOrAFolder) {
  hil::test::TempDir dir;
  hil::test::LabLog log;
  log.name = "inputs";
  log.duration_s = 2;
  const fs::path data = hil::test::make_lab_log(log, dir.path());
  const fs::path model = dir.write("model.yaml", hil::test::slurp(hil::test::nominal_model()));
  const fs::path link = dir.path() / "link.yaml";
  fs::create_symlink(model, link);
  const std::string data_before = hil::test::slurp(data), model_before = hil::test::slurp(model);
  const std::vector<std::pair<fs::path, std::string>> refused = {
      {data, ": is the input " + data.string() + ", which it would overwrite"},
      {model, ": is the input " + model.string() + ", which it would overwrite"},
      {link, ": is the input " + model.string() + ", which it would overwrite"},
      {dir.path(), ": is a folder; give the fitted model's file name"},
  };
  for (const auto& [target, why] : refused) {
    const CliRun r = hilbench("diagnose --model " + model.string() + " --data " + data.string() + " --out " +
                              (dir.path() / "d").string() + " --write-model " + target.string());
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_NE(r.out.find("--write-model " + target.string() + why), std::string::npos) << r.out;
    EXPECT_FALSE(fs::exists(dir.path() / "d")) << "refused before the fit, nothing written";
  }
  EXPECT_EQ(hil::test::slurp(data), data_before);
  EXPECT_EQ(hil::test::slurp(model), model_before);
  EXPECT_TRUE(fs::is_symlink(link));
}

// Each --data of diagnose is a run: one file given twice (by another spelling, or a link to it) was
// fitted as two runs, its rows counted twice; a candidate named twice was ranked twice. Refused
// before the fit, naming the option and the value.
TEST(CommandLine, DiagnoseRefusesAFileOrACandidateGivenTwice) {
  hil::test::TempDir dir;
  hil::test::LabLog log;
  log.name = "twice";
  log.duration_s = 2;
  const fs::path data = hil::test::make_lab_log(log, dir.path());
  const fs::path link = dir.path() / "link.csv";
  fs::create_symlink(data, link);
  const std::string model = hil::test::nominal_model().string(), out = (dir.path() / "d").string();
  for (const fs::path& again : {data, data.parent_path() / "." / data.filename(), link}) {
    const CliRun r = hilbench("diagnose --model " + model + " --data " + data.string() + " --data " + again.string() + " --out " +
                              out + " --quiet");
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_NE(r.out.find("--data " + again.string() + ": is the file of --data " + data.string() + " again"), std::string::npos)
        << r.out;
  }
  const CliRun r = hilbench("diagnose --model " + model + " --data " + data.string() +
                            " --candidates backlash_change,sensor_lag,backlash_change --out " + out + " --quiet");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("--candidates names 'backlash_change' twice"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(dir.path() / "d")) << "refused before the fit, nothing written";
}

// compare takes one file: a second --data was dropped unseen (the last one counted, as for every
// other option), where one who knows diagnose expects both compared.
TEST(CommandLine, CompareRefusesASecondDataFileAndPointsToDiagnose) {
  hil::test::TempDir dir;
  std::vector<std::string> files;
  for (const char* name : {"a", "b"}) {
    hil::test::LabLog log;
    log.name = name;
    log.duration_s = 2;
    files.push_back(hil::test::make_lab_log(log, dir.path()).string());
  }
  const CliRun r = hilbench("compare --model " + hil::test::nominal_model().string() + " --data " + files[0] + " --data " +
                            files[1] + " --out " + (dir.path() / "c").string() + " --quiet");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("--data given 2 times: compare takes one file (hilbench diagnose takes several --data"), std::string::npos)
      << r.out;
  EXPECT_FALSE(fs::exists(dir.path() / "c"));
}

TEST(CommandLine, CompareThenDiagnoseThenCompareTheFittedModel) {
  hil::test::TempDir dir;
  hil::test::Scenario s;
  s.name = "cli";
  s.duration_s = 15;
  s.seed = 77;
  s.encoder = false;
  s.reference_yaml = hil::test::reference_square(1.0, 1.4, 2.5);
  s.truth = [](const hil::plant::Plant& p) { return hil::test::with_block(p, "sensor_lag", "time_constant_s: 0.045"); };
  const auto data = hil::test::make_measurement(s, dir.path());
  const std::string model = hil::test::nominal_model().string(), out = dir.path().string();
  CliRun r = hilbench("compare --model " + model + " --data " + data.string() + " --out " + out + "/c1");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("fit "), std::string::npos);
  // A compare shorter than a second leaves no progress line in a log (hil::ProgressLine's delay).
  EXPECT_EQ(r.out.find("compare: "), std::string::npos) << r.out;
  r = hilbench("diagnose --model " + model + " --data " + data.string() + " --out " + out + "/d --write-model " + out +
               "/fitted.yaml");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("Found: sensor_lag"), std::string::npos) << r.out;
  r = hilbench("compare --model " + out + "/fitted.yaml --data " + data.string() + " --out " + out + "/c2 --quiet");
  ASSERT_EQ(r.code, 0) << r.out;
  const auto before = hil::test::read_json(dir.path() / "c1/compare.json");
  const auto after = hil::test::read_json(dir.path() / "c2/compare.json");
  EXPECT_LT(after.at("rmse_kpa").get<double>(), 0.5 * before.at("rmse_kpa").get<double>());
  EXPECT_GE(after.at("fit_pct").get<double>(), after.at("noise_floor_fit_pct").get<double>() - 1);
  // The fitted model is a plant file with the effect as a named block.
  const auto fitted = hil::cfg::Node::load_file(dir.path() / "fitted.yaml");
  EXPECT_NEAR(fitted.at("effects").at("sensor_lag").number("time_constant_s"), 0.045, 0.045 * 0.15);
  for (const char* f : {"c1/report.html", "d/report.html", "d/diagnosis.json", "c2/report.html"})
    EXPECT_TRUE(fs::exists(dir.path() / f)) << f;
}

}  // namespace
