// Loads generated reports in headless Chromium: every plot must render, with ink, without errors.
// Needs /usr/bin/chromium (scripts/setup.sh --test); without it these tests fail, they don't skip.
// The pages and a screenshot stay in <build>/tests/report/browser/ for a person to look at.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <random>
#include <sstream>

#include "hil/report/report.hpp"
#include "report/browser_check.hpp"
#include "sample_reports.hpp"

namespace fs = std::filesystem;
using hil::report::Band;
using hil::report::Bars;
using hil::report::Document;
using hil::report::Figure;
using hil::report::HLine;
using hil::report::Series;

namespace {

fs::path out_dir() {
  const fs::path dir = fs::path(HIL_BINARY_DIR) / "tests" / "report" / "browser";
  fs::create_directories(dir);
  return dir;
}

// A model-validation page with every figure kind the workbench uses; returns the plot count.
int add_validation(Document& doc) {
  const std::size_t n = 36000;  // 36 s at 1 kHz
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0, 0.02);
  std::vector<double> t(n), meas(n), model(n), resid(n), valve(n);
  for (std::size_t i = 0; i < n; ++i) {
    t[i] = static_cast<double>(i) * 1e-3;
    const double ref = 2.0 + (t[i] > 6 ? 1.5 : 0) + (t[i] > 20 ? -1.0 : 0);
    model[i] = ref + 0.3 * std::sin(0.5 * t[i]);
    valve[i] = 30 + 10 * std::sin(0.3 * t[i]);
    const double miss = (t[i] > 12 && t[i] < 15) ? 0.25 * std::sin(6 * t[i]) : 0.0;  // unmodelled
    meas[i] = model[i] + miss + noise(rng);
    resid[i] = meas[i] - model[i];
  }
  for (std::size_t i = 25000; i < 25400; ++i) meas[i] = resid[i] = NAN;  // telemetry dropout
  const std::vector<Band> failing = {{12.0, 15.0, "failing window 1"}, {27.5, 28.2, "failing window 2"}};

  doc.heading("Model validation: measured vs model");
  doc.note("No candidate effect explains the residual in failing window 1.", true);
  doc.figure(Figure{.title = "Pressure: measured vs model",
                    .x_label = "time [s]",
                    .y_label = "pressure [MPa]",
                    .series = {Series{.name = "measured", .x = t, .y = meas}, Series{.name = "model", .x = t, .y = model}},
                    .bands = failing,
                    .group = "validation"});
  doc.figure(Figure{.title = "Residual",
                    .x_label = "time [s]",
                    .y_label = "residual [MPa]",
                    .series = {Series{.name = "measured - model", .x = t, .y = resid}},
                    .bands = failing,
                    .hlines = {{0.05, "+tolerance"}, {-0.05, "-tolerance"}},
                    .group = "validation",
                    .height_px = 200});

  doc.bars(Bars{.title = "RMS error by regime",
                .y_label = "RMS error [MPa]",
                .categories = {"free motion", "closing contact", "opening contact", "gap change", "steady state"},
                .groups = {{"constant compensator", {0.021, 0.034, 0.052, 0.081, 0.012}},
                           {"adaptive compensator", {0.019, 0.022, 0.025, 0.031, 0.011}}}});

  const int lags = 200;
  std::vector<double> lag_s(lags), acf(lags);
  for (int k = 0; k < lags; ++k) {
    lag_s[static_cast<std::size_t>(k)] = k * 1e-3;
    acf[static_cast<std::size_t>(k)] = std::exp(-k / 25.0) * std::cos(k / 8.0);
  }
  const double bound = 1.96 / std::sqrt(static_cast<double>(n));
  doc.columns_begin(2);
  doc.figure(Figure{.title = "Residual autocorrelation",
                    .x_label = "lag [s]",
                    .y_label = "autocorrelation",
                    .series = {Series{.name = "ACF", .x = lag_s, .y = acf}},
                    .hlines = {{bound, "95 % bound"}, {-bound, ""}}});
  std::vector<double> f_hz(4097), psd(4097);
  for (std::size_t k = 0; k < f_hz.size(); ++k) {
    f_hz[k] = static_cast<double>(k) * 500.0 / 4096;  // includes the 0 Hz bin, left out on log axes
    psd[k] = 1e-4 / (1 + std::pow(f_hz[k] / 2.0, 2)) + 1e-8 + (std::abs(f_hz[k] - 0.95) < 0.1 ? 3e-4 : 0);
  }
  doc.figure(Figure{.title = "Residual spectrum",
                    .x_label = "frequency [Hz]",
                    .y_label = "PSD [MPa²/Hz]",
                    .series = {Series{.name = "residual PSD", .x = f_hz, .y = psd}},
                    .x_log = true,
                    .y_log = true});
  doc.columns_end();

  std::vector<double> sv, sr;
  for (std::size_t i = 0; i < n; i += 1) {
    if (std::isnan(resid[i])) continue;
    sv.push_back(valve[i]);
    sr.push_back(resid[i]);
  }
  doc.figure(Figure{.title = "Residual vs valve angle",
                    .x_label = "valve angle [deg]",
                    .y_label = "residual [MPa]",
                    .series = {Series{.name = "samples", .x = sv, .y = sr, .style = Series::Style::points}}});
  doc.table({"rank", "candidate effect", "explained variance [%]", "parameter", "BIC change"},
            {{"1", "Coulomb friction on the valve stem", "41.2", "0.18 N·m", "-312.5"},
             {"2", "Throat map offset", "12.7", "0.04 mm²", "-88.1"},
             {"3", "Transducer lag", "2.1", "3.5 ms", "4.9"}});

  doc.heading("Before / after fitting", 3);
  doc.columns_begin(2);
  for (const char* which : {"before", "after"}) {
    std::vector<double> r(n);
    const double scale = std::string(which) == "before" ? 1.0 : 0.3;
    for (std::size_t i = 0; i < n; ++i) r[i] = std::isnan(resid[i]) ? NAN : resid[i] * scale;
    doc.figure(Figure{.title = std::string("Residual ") + which,
                      .x_label = "time [s]",
                      .y_label = "residual [MPa]",
                      .series = {Series{.name = which, .x = t, .y = r}},
                      .bands = failing,
                      .group = "validation",
                      .height_px = 180});
  }
  doc.columns_end();
  return 8;
}

int add_stress(Document& doc) {
  doc.heading("An hour at 1 kHz, and edge cases");
  const std::size_t n = 3'600'000;
  Series hour{.name = "pressure (3.6 M points)", .x = std::vector<double>(n), .y = std::vector<double>(n)};
  for (std::size_t i = 0; i < n; ++i) {
    hour.x[i] = static_cast<double>(i) * 1e-3;
    hour.y[i] = 3 + 0.5 * std::sin(static_cast<double>(i) * 2e-5) + 0.01 * std::sin(static_cast<double>(i)) +
                (i % 400000 == 200000 ? 0.8 : 0.0);
  }
  doc.figure(Figure{.title = "One hour at 1 kHz (decimated with min/max per bucket)",
                    .x_label = "time [s]",
                    .y_label = "pressure [MPa]",
                    .series = {std::move(hour)}});
  doc.figure(Figure{.title = "Empty series",
                    .x_label = "time [s]",
                    .y_label = "pressure [MPa]",
                    .series = {Series{.name = "nothing recorded"}},
                    .height_px = 120});
  doc.figure(Figure{
      .title = "Hostile name </script><b>",
      .x_label = "x </script>",
      .y_label = "y",
      .series = {Series{
          .name = "</script><script>throw 1</script>", .x = {0, 1, 2, 3}, .y = {1, 3, NAN, 2}, .style = Series::Style::step}},
      .height_px = 140});
  doc.columns_begin(3);
  doc.bars(Bars{.title = "Bias by regime (negative, missing)",
                .y_label = "bias [MPa]",
                .categories = {"free motion", "closing contact with a long name", "opening", "gap"},
                .groups = {{"before", {-0.02, 0.015, NAN, -0.04}}, {"after", {-0.005, 0.004, 0.001, -0.01}}},
                .height_px = 220});
  doc.figure(Figure{.title = "Constant and single points",
                    .x_label = "time [s]",
                    .y_label = "gap [deg]",
                    .series = {Series{.name = "constant", .x = {0, 1, 2, 3}, .y = {2, 2, 2, 2}},
                               Series{.name = "one point", .x = {1.5}, .y = {2.1}, .style = Series::Style::points}},
                    .height_px = 220});
  std::vector<double> fx, fy;
  for (int k = 1; k < 3000; ++k) fx.push_back(0.01 * k), fy.push_back(1e-3 * std::pow(0.01 * k, -1.5) * (1 + 0.3 * std::sin(k)));
  doc.figure(Figure{.title = "Scatter on log axes",
                    .x_label = "frequency [Hz]",
                    .y_label = "gain",
                    .series = {Series{.name = "samples", .x = fx, .y = fy, .style = Series::Style::points}},
                    .x_log = true,
                    .y_log = true,
                    .height_px = 220});
  doc.columns_end();
  return 6;
}

}  // namespace

TEST(ReportInChromium, EveryPlotRendersWithInkAndNoErrors) {
  Document doc("Browser check: hilbench report with every figure kind");
  hil::test::add_campaign(doc, hil::test::simulate_campaign(3, 18.0));
  const int expected = 12 + add_validation(doc) + add_stress(doc);
  const fs::path file = out_dir() / "report.html";
  doc.write(file);

  const auto r = hil::test::check_report_in_chromium(file);
  ASSERT_TRUE(r.error.empty()) << r.summary();
  EXPECT_EQ(r.plot_errors, 0) << r.summary();
  EXPECT_EQ(r.plots, expected) << r.summary();
  ASSERT_EQ(static_cast<int>(r.canvases.size()), expected) << r.summary();
  int empty = 0;
  for (const auto& c : r.canvases) {
    EXPECT_TRUE(c.rendered);
    empty += c.empty;
  }
  EXPECT_EQ(empty, 1) << "only the empty-series figure says no data";
  EXPECT_GT(r.min_ink, 50) << r.summary();
  EXPECT_TRUE(r.ok()) << r.summary();
  EXPECT_EQ(r.dom.find("<script>throw"), std::string::npos);

  const fs::path png = out_dir() / "report.png";
  const std::string err = hil::test::screenshot_in_chromium(file, png, 1400, 2000);
  ASSERT_TRUE(err.empty()) << err;
  EXPECT_GT(fs::file_size(png), 20'000u) << "a blank page compresses to almost nothing";
}

// Zoom, pan, reset, wheel, hover, legend and table sorting, driven by synthetic events from
// interaction_check.js appended to the page.
TEST(ReportInChromium, InteractionsWork) {
  Document doc("Interactions");
  hil::test::add_campaign(doc, hil::test::simulate_campaign(2, 6.0));
  add_validation(doc);
  std::string page = doc.html();
  std::ifstream js(fs::path(HIL_SOURCE_DIR) / "tests" / "report" / "interaction_check.js");
  std::stringstream check;
  check << js.rdbuf();
  ASSERT_FALSE(check.str().empty());
  page.insert(page.rfind("</body>"), "<script>\n" + check.str() + "</script>\n");
  const fs::path file = out_dir() / "interactions.html";
  std::ofstream(file) << page;

  const auto r = hil::test::check_report_in_chromium(file);
  ASSERT_TRUE(r.error.empty()) << r.summary();
  EXPECT_EQ(r.body_attribute("data-interaction"), "ok");
  EXPECT_EQ(r.plot_errors, 0) << r.summary();
}

// The helper must notice a plot that fails: corrupt one figure's data.
TEST(ReportInChromium, HelperReportsABrokenPlot) {
  Document doc("broken");
  doc.figure(Figure{.title = "fine", .x_label = "x", .y_label = "y", .series = {Series{.name = "s", .x = {0, 1}, .y = {0, 1}}}});
  doc.figure(
      Figure{.title = "broken", .x_label = "x", .y_label = "y", .series = {Series{.name = "s", .x = {0, 1}, .y = {0, 1}}}});
  std::string page = doc.html();
  const auto second = page.find("\"kind\":\"plot\"", page.find("\"kind\":\"plot\"") + 1);
  ASSERT_NE(second, std::string::npos);
  page.replace(second, 13, "\"kind\":plot!");
  const fs::path file = out_dir() / "broken.html";
  std::ofstream(file) << page;

  const auto r = hil::test::check_report_in_chromium(file);
  ASSERT_TRUE(r.error.empty()) << r.summary();
  EXPECT_EQ(r.plots, 1);
  EXPECT_EQ(r.plot_errors, 1);
  EXPECT_FALSE(r.first_error.empty());
  EXPECT_FALSE(r.ok());
}
