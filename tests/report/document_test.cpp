// The Document: page structure, escaping, atomic write, size and speed on realistic data.
#include "hil/report/report.hpp"

#include <gtest/gtest.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cmath>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "assets.hpp"
#include "sample_reports.hpp"
#include "temp_file.hpp"

namespace fs = std::filesystem;
using hil::report::Bars;
using hil::report::Document;
using hil::report::Figure;
using hil::report::Series;
using hil::test::slurp;
using hil::test::TempDir;

namespace {

std::size_t count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto p = text.find(what); p != std::string::npos; p = text.find(what, p + 1)) ++n;
  return n;
}

// What a folder holds: a write that leaves its temporary behind has two entries.
std::size_t entries(const fs::path& dir) { return static_cast<std::size_t>(std::distance(fs::directory_iterator(dir), {})); }

Document small_doc() {
  Document doc("small");
  doc.figure(Figure{
      .title = "f", .x_label = "time [s]", .y_label = "y", .series = {Series{.name = "s", .x = {0, 1, 2}, .y = {1, 2, 3}}}});
  return doc;
}

}  // namespace

TEST(Document, HostileTextCannotBreakThePage) {
  Document doc("<script>alert('title')</script>");
  doc.heading("<b>heading</b>");
  doc.paragraph("<b>bold</b> & <i>it</i>");
  doc.note("<img src=x onerror=alert(1)>", true);
  doc.table({"<th>"}, {{"<td>"}, {"</table>"}});
  doc.figure(Figure{.title = "</figure><script>alert(2)</script>",
                    .x_label = "</script>",
                    .y_label = "<b>y</b>",
                    .series = {Series{.name = "</script><script>alert(3)</script>",
                                      .x = {0, 1},
                                      .y = {0, 1},
                                      .color = "red\"></canvas><script>alert(4)</script>"}},
                    .bands = {{0, 1, "<!-- band", ""}},
                    .hlines = {{0.5, "</script>"}}});
  doc.bars(Bars{.title = "<b>", .y_label = "<i>", .categories = {"</script>"}, .groups = {{"<g>", {1.0}}}});
  std::string page = doc.html();
  // The embedded plotting library is trusted text with markup of its own: checked apart.
  const auto lib = page.find(hil::report::detail::kDygraphJs);
  ASSERT_NE(lib, std::string::npos);
  page.erase(lib, hil::report::detail::kDygraphJs.size());
  EXPECT_EQ(page.find("<b>"), std::string::npos);
  EXPECT_EQ(page.find("<i>"), std::string::npos);
  EXPECT_EQ(page.find("<img"), std::string::npos);
  EXPECT_EQ(page.find("<!-- band"), std::string::npos);
  EXPECT_EQ(page.find("<script>alert"), std::string::npos);
  // Exactly the page's own scripts: one data script per figure, dygraphs and the plotting layer.
  EXPECT_EQ(count(page, "<script"), 4u);
  EXPECT_EQ(count(page, "</script>"), 4u);
  EXPECT_EQ(count(page, "<figure"), 2u);
  EXPECT_EQ(count(page, "</figure>"), 2u);
}

TEST(Document, RejectsMismatchedData) {
  Document doc("bad");
  EXPECT_THROW(doc.figure(Figure{.title = "t", .series = {Series{.name = "s", .x = {0, 1}, .y = {0}}}}), std::invalid_argument);
  EXPECT_THROW(doc.bars(Bars{.title = "b", .categories = {"a", "b"}, .groups = {{"g", {1.0}}}}), std::invalid_argument);
  EXPECT_THROW(doc.columns_end(), std::logic_error);
  doc.columns_begin(2);
  EXPECT_THROW(doc.columns_begin(2), std::logic_error);
  doc.columns_end();
}

TEST(Document, TablesMarkNumericCells) {
  Document doc("t");
  doc.table({"name", "value"}, {{"rms", "0.0123"}, {"share", "12.5 %"}, {"note", "n/a"}});
  const std::string page = doc.html();
  EXPECT_EQ(count(page, "<td class=\"num\">"), 2u);
}

// A heatmap without a pass band: every value printed in its cell, a cell without a value blank,
// marked cells flagged, the labels escaped. Coloured red where marked (failing) and green elsewhere;
// with no marks at all, from green (hue 120, the smallest) to red (hue 0, the largest).
TEST(Document, HeatmapColoursAndFlagsCells) {
  Document doc("h");
  hil::report::Heatmap h{.title = "<iae>",
                         .x_label = "gap",
                         .y_label = "noise",
                         .x_ticks = {"0.5", "1"},
                         .y_ticks = {"0", "2"},
                         .values = {{1.0, 2.0}, {3.0, NAN}},
                         .marked = {{false, false}, {true, false}}};
  doc.heatmap(h);
  const std::string page = doc.html();
  EXPECT_NE(page.find("background:hsl(120,60%,76%);\">1</td>"), std::string::npos);
  EXPECT_NE(page.find("background:hsl(120,60%,76%);\">2</td>"), std::string::npos);
  EXPECT_NE(page.find("background:hsl(0,60%,76%);outline:2px solid #b00;outline-offset:-2px;font-weight:bold;\">3 &#x2717;</td>"),
            std::string::npos);
  EXPECT_NE(page.find("red where a point of the cell fails"), std::string::npos);
  EXPECT_EQ(count(page, "&#x2717;"), 1u);
  EXPECT_NE(page.find("&lt;iae&gt;"), std::string::npos);

  Document plain("h");
  h.marked.clear();
  plain.heatmap(h);
  const std::string ranked = plain.html();
  EXPECT_NE(ranked.find("background:hsl(120,70%,72%);\">1</td>"), std::string::npos);
  EXPECT_NE(ranked.find("background:hsl(60,70%,72%);\">2</td>"), std::string::npos);
  EXPECT_NE(ranked.find("background:hsl(0,70%,72%);\">3</td>"), std::string::npos);
  EXPECT_NE(ranked.find("style=\"\">-</td>"), std::string::npos);
  EXPECT_NE(ranked.find("green for the smallest value to red for the largest"), std::string::npos);
  h.values.pop_back();
  EXPECT_THROW(doc.heatmap(h), std::invalid_argument);
}

// With a pass band the colour says pass or fail, not the value's rank: a "higher is better" metric
// (pass at >= 2) whose smallest cell fails is red there, though it is the smallest value; passing
// cells are green, darker the further inside; a missing value counts as failing.
TEST(Document, HeatmapColoursByThePassBand) {
  Document doc("h");
  doc.heatmap(hil::report::Heatmap{.title = "margin",
                                   .x_ticks = {"a", "b", "c", "d"},
                                   .y_ticks = {"1"},
                                   .values = {{1.0, 2.5, 4.0, NAN}},
                                   .marked = {{true, false, false, true}},
                                   .pass_min = 2.0});
  const std::string page = doc.html();
  // 1 is 1 below the bound, the furthest out: the darkest red (86 - 22 = 64 % lightness).
  EXPECT_NE(page.find("background:hsl(0,60%,64%);outline"), std::string::npos) << page;
  // 2.5 is 0.5 inside of at most 2: a quarter of the way to the darkest green; 4 the darkest.
  EXPECT_NE(page.find("background:hsl(120,60%,80%);\">2.5</td>"), std::string::npos);
  EXPECT_NE(page.find("background:hsl(120,60%,64%);\">4</td>"), std::string::npos);
  EXPECT_NE(page.find("background:hsl(0,60%,64%);outline:2px solid #b00;outline-offset:-2px;font-weight:bold;\">- &#x2717;"),
            std::string::npos);
  EXPECT_EQ(count(page, "hsl(120,"), 2u);
  EXPECT_EQ(count(page, "hsl(0,"), 2u);
  EXPECT_NE(page.find("green passes (&ge; 2), red fails"), std::string::npos);

  Document upper("h");
  upper.heatmap(hil::report::Heatmap{
      .title = "iae", .x_ticks = {"a", "b"}, .y_ticks = {"1"}, .values = {{0.1, 0.3}}, .pass_min = 0.0, .pass_max = 0.2});
  const std::string both = upper.html();
  EXPECT_NE(both.find("background:hsl(120,60%,64%);\">0.1</td>"), std::string::npos) << both;
  EXPECT_NE(both.find("background:hsl(0,60%,64%);\">0.3</td>"), std::string::npos);
  EXPECT_NE(both.find("(&ge; 0 and &le; 0.2)"), std::string::npos);
}

// The plot help and the plotting library come with plots only: a page of tables and maps (a sweep
// report) has neither; a page with one figure or one bar chart has both.
TEST(Document, PlotHelpOnlyOnPagesWithPlots) {
  Document tables("tables");
  tables.table({"a"}, {{"1"}});
  tables.heatmap(hil::report::Heatmap{.title = "m", .x_ticks = {"a"}, .y_ticks = {"1"}, .values = {{1.0}}});
  const std::string none = tables.html();
  const auto library = hil::report::detail::kDygraphJs.substr(0, 200);
  EXPECT_EQ(none.find("class=\"hil-help\""), std::string::npos);
  EXPECT_EQ(none.find("drag to zoom"), std::string::npos);
  EXPECT_EQ(none.find(library), std::string::npos);

  const std::string one = small_doc().html();
  EXPECT_NE(one.find("class=\"hil-help\">Plots: drag to zoom"), std::string::npos);
  EXPECT_NE(one.find(library), std::string::npos);
  Document bars("bars");
  bars.bars(Bars{.title = "b", .categories = {"a"}, .groups = {{"g", {1.0}}}});
  EXPECT_NE(bars.html().find("class=\"hil-help\""), std::string::npos);
}

TEST(DocumentWrite, WritesTheWholePageAndNoTemporary) {
  TempDir dir;
  const auto file = dir.path() / "report.html";
  const auto doc = small_doc();
  doc.write(file);
  EXPECT_EQ(slurp(file), doc.html());
  EXPECT_EQ(entries(dir.path()), 1u);
  doc.write(file);  // replaces
  EXPECT_EQ(entries(dir.path()), 1u);
}

TEST(DocumentWrite, FailedRenameLeavesNoTemporary) {
  TempDir dir;
  const auto target = dir.path() / "report.html";
  fs::create_directory(target);
  fs::create_directory(target / "keep");  // a non-empty folder cannot be renamed over
  try {
    small_doc().write(target);
    FAIL() << "write over a directory should throw";
  } catch (const std::system_error& e) {
    EXPECT_NE(std::string(e.what()).find("report.html"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(fs::is_directory(target / "keep"));
  EXPECT_EQ(entries(dir.path()), 1u);
}

TEST(DocumentWrite, MissingFolderThrowsNamingTheFile) {
  try {
    small_doc().write("/nonexistent-hil-folder/report.html");
    FAIL() << "should throw";
  } catch (const std::system_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-hil-folder/report.html"), std::string::npos);
  }
}

// A write that fails halfway (here: the file size limit, as a full disk would) must leave the
// previous report whole and no partial file behind.
TEST(DocumentWrite, FailureHalfwayKeepsThePreviousReport) {
  TempDir dir;
  const auto file = dir.path() / "report.html";
  { std::ofstream(file) << "previous report"; }
  const auto doc = small_doc();
  ASSERT_GT(doc.html().size(), 8192u);

  rlimit old{};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old), 0);
  const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);  // so write() returns EFBIG instead
  rlimit small = old;
  small.rlim_cur = 4096;
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &small), 0);
  bool threw = false;
  try {
    doc.write(file);
  } catch (const std::system_error&) {
    threw = true;
  }
  ::setrlimit(RLIMIT_FSIZE, &old);
  std::signal(SIGXFSZ, old_handler);
  EXPECT_TRUE(threw);
  EXPECT_EQ(slurp(file), "previous report");
  EXPECT_EQ(entries(dir.path()), 1u);
}

// Budget: `hilbench sim` writes a 3-run, 18-s campaign report in its ~20 ms command.
TEST(DocumentSize, CampaignReportIsSmallAndQuick) {
  using clock = std::chrono::steady_clock;
  const auto runs = hil::test::simulate_campaign(3, 18.0);
  TempDir dir;
  const auto t0 = clock::now();
  Document doc("Campaign report");
  hil::test::add_campaign(doc, runs);
  const auto t1 = clock::now();
  doc.write(dir.path() / "report.html");
  const auto t2 = clock::now();
  const auto size = fs::file_size(dir.path() / "report.html");
  const double build_ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
  const double write_ms = std::chrono::duration<double, std::milli>(t2 - t1).count();
  std::printf(
      "campaign report (3 runs x 18 s at 1 kHz, 12 figures): %.0f kB; "
      "build %.1f ms, write %.1f ms\n",
      static_cast<double>(size) / 1e3, build_ms, write_ms);
  EXPECT_LT(size, 3'000'000u);
}

TEST(DocumentSize, HourAt1kHzDecimatesQuickly) {
  const std::size_t n = 3'600'000;
  Series s{.name = "pressure", .x = std::vector<double>(n), .y = std::vector<double>(n)};
  for (std::size_t i = 0; i < n; ++i) {
    s.x[i] = static_cast<double>(i) * 1e-3;
    s.y[i] = 3 + std::sin(static_cast<double>(i) * 1e-4) + (i % 100000 == 0 ? 1.0 : 0.0);
  }
  Figure fig{.title = "1 h at 1 kHz", .x_label = "time [s]", .y_label = "pressure [MPa]"};
  fig.series.push_back(std::move(s));
  Document doc("hour");
  const auto t0 = std::chrono::steady_clock::now();
  doc.figure(fig);
  const auto t1 = std::chrono::steady_clock::now();
  const auto page = doc.html();
  std::printf("3.6 M-point series: figure() %.1f ms, page %.0f kB\n", std::chrono::duration<double, std::milli>(t1 - t0).count(),
              static_cast<double>(page.size()) / 1e3);
  EXPECT_LT(page.size(), 400'000u);
  EXPECT_NE(page.find("\"n\":3600000"), std::string::npos);
}

TEST(Document, SeriesOfOneXAreWrittenWithOneXEveryOtherWithItsOwn) {
  const std::size_t n = 30000;
  std::vector<double> t(n), ref(n), meas(n), valve(n), t2(n / 3), other(n / 3);
  for (std::size_t i = 0; i < n; ++i) {
    t[i] = 1e-3 * static_cast<double>(i);
    ref[i] = i < n / 2 ? 1.0 : 2.0;
    meas[i] = ref[i] + 0.1 * std::sin(0.37 * static_cast<double>(i));
    valve[i] = i == 12345 ? NAN : std::cos(0.001 * static_cast<double>(i));
  }
  for (std::size_t i = 0; i < t2.size(); ++i)
    t2[i] = 3e-3 * static_cast<double>(i), other[i] = std::sin(0.01 * static_cast<double>(i));
  Document doc("shared");
  doc.figure(Figure{.title = "f",
                    .series = {Series{.name = "reference", .x = t, .y = ref, .style = Series::Style::step},
                               Series{.name = "measured", .x = t, .y = meas}, Series{.name = "other", .x = t2, .y = other},
                               Series{.name = "valve", .x = t, .y = valve}}});
  const std::string page = doc.html();
  const std::string open = "class=\"hil-data\">";
  const auto a = page.find(open) + open.size();
  const auto spec = nlohmann::json::parse(page.substr(a, page.find("</script>", a) - a));
  const auto& s = spec["series"];
  ASSERT_EQ(s.size(), 4u);
  ASSERT_TRUE(s[0].contains("x"));
  EXPECT_EQ(s[1]["xOf"], 0);
  EXPECT_EQ(s[3]["xOf"], 0);
  EXPECT_FALSE(s[1].contains("x"));
  ASSERT_TRUE(s[2].contains("x")) << "a series of another x keeps its own";
  EXPECT_FALSE(s[2].contains("xOf"));
  const auto& x = s[0]["x"];
  EXPECT_LE(x.size(), 3u * hil::report::kMaxBuckets);
  for (int i : {0, 1, 3}) EXPECT_EQ(s[i]["y"].size(), x.size()) << "series " << i;
  EXPECT_EQ(s[2]["y"].size(), s[2]["x"].size());
  // The step's change, the measurement's extremes and the valve's gap survive on the shared x.
  EXPECT_GT(std::count(s[0]["y"].begin(), s[0]["y"].end(), 2.0), 0);
  EXPECT_EQ(std::count(s[3]["y"].begin(), s[3]["y"].end(), nullptr), 1);
  double mx = -INFINITY;
  for (const auto& v : s[1]["y"]) mx = std::max(mx, v.get<double>());
  EXPECT_NEAR(mx, *std::max_element(meas.begin(), meas.end()), 1e-5);  // written with 6 digits
}
