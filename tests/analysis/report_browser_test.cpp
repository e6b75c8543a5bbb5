// The workbench's report.html files in headless Chromium: every plot renders, with ink, without
// script errors; screenshots stay in <build>/tests/analysis/browser/ for a person to look at.
#include <gtest/gtest.h>

#include "report/browser_check.hpp"
#include "temp_file.hpp"
#include "workbench_test_util.hpp"

namespace {

namespace fs = std::filesystem;

fs::path out_dir() {
  const fs::path d = fs::path(HIL_BINARY_DIR) / "tests" / "analysis" / "browser";
  fs::create_directories(d);
  return d;
}

void expect_renders(const fs::path& html, int min_plots, const std::string& png_name) {
  const auto r = hil::test::check_report_in_chromium(html);
  EXPECT_TRUE(r.ok()) << r.summary();
  EXPECT_GE(r.plots, min_plots) << r.summary();
  EXPECT_EQ(r.plot_errors, 0) << r.first_error;
  EXPECT_GT(r.min_ink, 50) << r.summary();
  const std::string err = hil::test::screenshot_in_chromium(html, out_dir() / png_name, 1400, 2600);
  EXPECT_TRUE(err.empty()) << err;
}

TEST(ReportBrowser, CompareAndDiagnoseReportsRender) {
  hil::test::TempDir dir;
  hil::test::Scenario s;
  s.name = "browser";
  s.duration_s = 20;
  s.seed = 116;
  s.encoder = false;
  s.reference_yaml = hil::test::reference_random(4, 0.9, 1.5, 1.5, 3.0);
  s.truth = [](const hil::plant::Plant& p) {
    return hil::test::with_block(p, "backlash_change", "{gap_deg: 1.0, step_time_s: 10, step_deg: 0.8}");
  };
  const fs::path data = hil::test::make_measurement(s, dir.path());
  const fs::path out = out_dir();
  hil::test::run_compare(hil::test::nominal_model(), data, out / "compare");
  const auto d = hil::test::run_diagnose(hil::test::nominal_model(), data, out / "diagnose");
  ASSERT_EQ(d.at("added").size(), 1u);
  // compare: overlay, residual, drive, regime bars, ACF, XCF, spectrum, after-reversal, 4 binned views.
  expect_renders(out / "compare" / "report.html", 12, "compare.png");
  // diagnose: before/after overlay and residuals, regime bars, ranking bars, then the compare views.
  expect_renders(out / "diagnose" / "report.html", 15, "diagnose.png");
  const std::string dom = hil::test::check_report_in_chromium(out / "diagnose" / "report.html").dom;
  EXPECT_NE(dom.find("backlash_change"), std::string::npos);
  EXPECT_NE(dom.find("Before and after"), std::string::npos);
}

TEST(ReportBrowser, UnexplainedReportRenders) {
  hil::test::TempDir dir;
  hil::test::Scenario s;
  s.name = "unexplained";
  s.duration_s = 15;
  s.seed = 117;
  s.reference_yaml = hil::test::reference_square(1.0, 1.4, 2.5);
  s.truth = [](const hil::plant::Plant& p) {
    return hil::test::with_block(p, "test_chamber_oscillation", "{amplitude_kpa: 10, frequency_hz: 9.1}");
  };
  const fs::path data = hil::test::make_measurement(s, dir.path());
  const auto d = hil::test::run_diagnose(hil::test::nominal_model(), data, out_dir() / "unexplained");
  EXPECT_FALSE(d.at("explained").get<bool>());
  expect_renders(out_dir() / "unexplained" / "report.html", 12, "unexplained.png");
}

// diagnose --data a --data b: the files table, each file's before/after and remaining views,
// each file's plots zooming together and apart from the other file's (its own clock).
TEST(ReportBrowser, SeveralFilesReportRenders) {
  hil::test::TempDir dir;
  std::vector<fs::path> files;
  for (int i = 0; i < 2; ++i) {
    hil::test::LabLog log;
    log.name = "browser_rig" + std::to_string(i + 1);
    log.t0_s = 10.0 + 100.0 * i;
    log.duration_s = 10;
    log.seed = 118 + static_cast<std::uint64_t>(i);
    log.noise_kpa = 2;
    log.truth = [](const hil::plant::Plant& p) { return hil::test::with_block(p, "sensor_lag", "time_constant_s: 0.03"); };
    log.command_deg = hil::test::command_triangle(8.0, 13.0, i == 0 ? 5.0 : 20.0, 0.5);
    files.push_back(hil::test::make_lab_log(log, dir.path()));
  }
  const auto d = hil::test::run_diagnose(hil::test::nominal_model(), hil::analysis::DataFiles(files), out_dir() / "several");
  ASSERT_EQ(d.at("added").size(), 1u) << hil::test::brief(d);
  // Per file: overlay, residuals, regime bars, then compare's 12 views; plus the ranking bars.
  expect_renders(out_dir() / "several" / "report.html", 2 * 15, "several.png");
  const std::string dom = hil::test::check_report_in_chromium(out_dir() / "several" / "report.html").dom;
  EXPECT_NE(dom.find("Before and after: file 1, browser_rig1.csv"), std::string::npos);
  EXPECT_NE(dom.find("Before and after: file 2, browser_rig2.csv"), std::string::npos);
  EXPECT_NE(dom.find("shared by all of them"), std::string::npos);
}

}  // namespace
