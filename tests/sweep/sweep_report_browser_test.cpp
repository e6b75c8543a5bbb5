// The sweep report as a reader sees it: a reduced paper_vs_robust (paper_adaptive, 2 gaps x 2
// noises x 2 seeds, both observers) swept by the real hilbench, its report.html loaded in headless
// Debian Chromium, and the DOM Chromium leaves read back: the axes named in words with units, each
// cell's failing-point count and colour checked against what sweep.csv says, for both observers'
// maps, each map against its own threshold.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "report/browser_check.hpp"
#include "run_command.hpp"
#include "temp_file.hpp"

namespace fs = std::filesystem;
using hil::test::run_command;
using hil::test::slurp;
using hil::test::source_path;
using hil::test::TempDir;

namespace {

// sweep.csv as a column-name -> values table (no field of this sweep is quoted).
struct Csv {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  std::size_t col(const std::string& name) const {
    for (std::size_t i = 0; i < header.size(); ++i)
      if (header[i] == name) return i;
    ADD_FAILURE() << "sweep.csv has no column " << name;
    return 0;
  }
};

Csv read_csv(const fs::path& file) {
  Csv csv;
  std::stringstream in(slurp(file));
  for (std::string line; std::getline(in, line);) {
    std::vector<std::string> cells;
    std::stringstream l(line);
    for (std::string c; std::getline(l, c, ',');) cells.push_back(c);
    (csv.header.empty() ? csv.header : csv.rows.emplace_back()) = cells;
  }
  return csv;
}

struct Cell {
  std::string value_text, colour;  // colour: "hil-pass", "hil-fail" or "" (by range)
  long failing = -1, points = -1;
};

// The map captioned `metric` in the DOM: its header's first cell and its cells by [y][x].
struct DomMap {
  std::string corner;  // "y label \ x label"
  std::vector<std::string> x_ticks, y_ticks;
  std::vector<std::vector<Cell>> cells;
};

DomMap dom_map(const std::string& dom, const std::string& metric) {
  DomMap m;
  const auto at = dom.find("<b>" + metric + "</b>");
  if (at == std::string::npos) return m;
  const auto end = dom.find("</table>", at);
  const std::string table = dom.substr(at, end - at);
  const std::string head = table.substr(0, table.find("</thead>"));
  const std::regex th("<th>([^<]*)</th>");
  for (auto it = std::sregex_iterator(head.begin(), head.end(), th); it != std::sregex_iterator(); ++it)
    (m.corner.empty() ? m.corner : m.x_ticks.emplace_back()) = (*it)[1];
  const std::string body = table.substr(table.find("<tbody>"));
  const std::regex row("<tr><th>([^<]*)</th>(.*?)</tr>");
  const std::regex td(
      "<td class=\"num ?([a-z-]*)\" style=\"[^\"]*\">([^<]*)<br><small class=\"hil-cell-note\">([0-9]+) of ([0-9]+) "
      "fail</small></td>");
  for (auto r = std::sregex_iterator(body.begin(), body.end(), row); r != std::sregex_iterator(); ++r) {
    m.y_ticks.push_back((*r)[1]);
    auto& cells = m.cells.emplace_back();
    const std::string tds = (*r)[2];
    for (auto c = std::sregex_iterator(tds.begin(), tds.end(), td); c != std::sregex_iterator(); ++c)
      cells.push_back({(*c)[2], (*c)[1], std::stol((*c)[3]), std::stol((*c)[4])});
  }
  return m;
}

}  // namespace

TEST(SweepReportBrowser, AxesInWordsFailingCountsAndColoursPerObserver) {
  TempDir dir;
  // paper_vs_robust, reduced: the same campaign, axes, thresholds and maps over 2 x 2 cells and 2
  // seeds (8 points, 3 runs of 18 s each); the gap-error maps get thresholds of their own, and the
  // noise axis its own label and unit, while the gap axis takes the default from the campaign's keys.
  const auto sweep =
      dir.write("pvr.yaml",
                "name: pvr\ncampaign: " + source_path("configs/campaigns/paper_adaptive.yaml").string() +
                    "\naxes:\n"
                    "  - {path: campaign.gap.initial_deg, values: [0.5, 3]}\n"
                    "  - {path: \"campaign.gap.changes[0].step.to_deg\", relative_to: campaign.gap.initial_deg, values: [1]}\n"
                    "  - {path: campaign.sensor_noise_kpa, values: [0, 5], label: transducer noise, unit: kPa RMS}\n"
                    "  - {path: campaign.seed, values: [1, 2]}\n"
                    "thresholds:\n"
                    "  adaptive.stall_vs_none: {max: 0.5}\n"
                    "  adaptive_paper.stall_vs_none: {max: 0.5}\n"
                    "maps:\n"
                    "  - {metric: adaptive.stall_vs_none, x: campaign.gap.initial_deg, y: campaign.sensor_noise_kpa}\n"
                    "  - {metric: adaptive_paper.stall_vs_none, x: campaign.gap.initial_deg, y: campaign.sensor_noise_kpa}\n"
                    "  - {metric: adaptive.gap_error_deg, x: campaign.gap.initial_deg, y: campaign.sensor_noise_kpa, max: 0.3}\n"
                    "  - {metric: adaptive_paper.gap_error_deg, x: campaign.gap.initial_deg, y: campaign.sensor_noise_kpa, "
                    "max: 0.3}\n"
                    "worst_by: adaptive_paper.stall_vs_none\n");
  const fs::path out = dir.path() / "out";
  const auto r = run_command(hil::test::hilbench() + " sweep " + sweep.string() + " --out " + out.string() + " --quiet");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto result = hil::test::check_report_in_chromium(out / "report.html");
  ASSERT_TRUE(result.error.empty()) << result.error;
  const std::string& dom = result.dom;

  const Csv csv = read_csv(out / "sweep.csv");
  ASSERT_EQ(csv.rows.size(), 8u);
  const std::size_t gap = csv.col("campaign.gap.initial_deg"), noise = csv.col("campaign.sensor_noise_kpa");
  const std::vector<std::string> gaps{"0.5", "3"}, noises{"0", "5"};
  const auto number = [](const std::string& s) { return s == "nan" ? std::nan("") : std::stod(s); };
  // A point fails for a run where the run's stall exceeds its threshold or one of its campaign's
  // checks failed; on a map with a threshold of its own, also where the map's metric exceeds it.
  const auto fails_for = [&](const std::vector<std::string>& row, const std::string& run, const std::string& metric, double max) {
    const double stall = number(row[csv.col(run + ".stall_vs_none")]), v = number(row[csv.col(metric)]);
    return !(stall <= 0.5) || number(row[csv.col(run + ".checks_failed")]) != 0 || !(v <= max);
  };
  struct Expect {
    std::string run, metric;
    double max;
  };
  const Expect maps[] = {{"adaptive", "adaptive.stall_vs_none", 0.5},
                         {"adaptive_paper", "adaptive_paper.stall_vs_none", 0.5},
                         {"adaptive", "adaptive.gap_error_deg", 0.3},
                         {"adaptive_paper", "adaptive_paper.gap_error_deg", 0.3}};
  long fail_cells[2] = {0, 0}, pass_cells[2] = {0, 0};  // per observer, over its maps
  for (const Expect& e : maps) {
    SCOPED_TRACE(e.metric);
    const DomMap m = dom_map(dom, e.metric);
    // Axes in words with their units: the gap from the campaign key's default, the noise from the file.
    EXPECT_EQ(m.corner, "transducer noise (kPa RMS) \\ initial gap (deg)");
    EXPECT_EQ(m.x_ticks, gaps);
    EXPECT_EQ(m.y_ticks, noises);
    ASSERT_EQ(m.cells.size(), 2u);
    for (std::size_t y = 0; y < 2; ++y) {
      ASSERT_EQ(m.cells[y].size(), 2u);
      for (std::size_t x = 0; x < 2; ++x) {
        double sum = 0;
        long n = 0, failing = 0;
        for (const auto& row : csv.rows) {
          if (row[gap] != gaps[x] || row[noise] != noises[y]) continue;
          sum += number(row[csv.col(e.metric)]);
          ++n;
          failing += fails_for(row, e.run, e.metric, e.max) ? 1 : 0;
        }
        const double mean = sum / static_cast<double>(n);
        const Cell& c = m.cells[y][x];
        SCOPED_TRACE("gap " + gaps[x] + ", noise " + noises[y] + ", mean " + std::to_string(mean));
        EXPECT_EQ(c.points, n);
        EXPECT_EQ(c.failing, failing);
        // The colour is the cell's mean against this map's threshold, whatever the other observer did.
        EXPECT_EQ(c.colour, mean <= e.max ? "hil-pass" : "hil-fail");
        if (std::isnan(mean)) {
          EXPECT_EQ(c.value_text, "-");
        } else {
          EXPECT_NEAR(std::stod(c.value_text), mean, 0.005 * std::abs(mean) + 1e-9);  // 3 significant digits
        }
        const int observer = e.run == "adaptive" ? 0 : 1;
        (mean <= e.max ? pass_cells : fail_cells)[observer] += 1;
      }
    }
  }
  // The sweep shows both verdicts: the robust observer passes cells where the paper's fails.
  EXPECT_GT(pass_cells[0], fail_cells[0]);
  EXPECT_GT(fail_cells[1], pass_cells[1]);

  // Pass counts per run, each from its own thresholds and checks.
  for (const std::string run : {"adaptive", "adaptive_paper"}) {
    long passed = 0;
    for (const auto& row : csv.rows) passed += fails_for(row, run, run + ".stall_vs_none", 0.5) ? 0 : 1;
    EXPECT_NE(dom.find("Run " + run + ": " + std::to_string(passed) + " of 8 points pass"), std::string::npos) << run;
  }
  // The worst points link to their traces: a campaign report that exists and names the campaign.
  const std::regex link("<a href=\"(points/([0-9]+)/paper_adaptive/report.html)\">");
  long links = 0;
  for (auto it = std::sregex_iterator(dom.begin(), dom.end(), link); it != std::sregex_iterator(); ++it, ++links) {
    const std::string report = slurp(out / (*it)[1].str());
    EXPECT_NE(report.find("paper_adaptive"), std::string::npos) << (*it)[1];
  }
  EXPECT_EQ(links, 3);
}
