// A page of the one-hour 1 kHz run report's shape, without a run: 5 linked time plots of 1000
// min/max buckets each (the run report's kOverviewBuckets) over 3.6 M noisy samples per series
// (a zigzag envelope, as measured data gives), an event marker, a table and a bar chart; written
// by this tree's report writer. For A/B of report.js in Chromium (ab_pages.mjs) where no hour's
// run folder is at hand:
//   scripts/build.sh report_hour_shape && build/benchmarks/report/report_hour_shape /tmp/hour_shape.html
#include <cmath>
#include <cstdio>
#include <random>

#include "hil/report/report.hpp"

using namespace hil::report;

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: report_hour_shape OUT.html\n");
    return 2;
  }
  const std::size_t n = 3'600'000;
  std::vector<double> t(n), p(n), ref(n), motor(n), valve(n), gt(n), ge(n), touch(n);
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0, 0.004);
  for (std::size_t i = 0; i < n; ++i) {
    const double s = i * 1e-3;
    t[i] = s;
    ref[i] = 1.0 + 0.5 * (std::fmod(s, 20.0) < 10 ? 1 : -1);
    p[i] = ref[i] - 0.5 * std::exp(-std::fmod(s, 10.0)) * (std::fmod(s, 20.0) < 10 ? 1 : -1) + noise(rng);
    motor[i] = 15 + 10 * std::sin(s * 0.3) + 20 * noise(rng);
    valve[i] = motor[i] - 1 + 10 * noise(rng);
    gt[i] = 2 + 0.5 * (s > 60 ? (s - 60) / 3540 : 0);
    ge[i] = gt[i] + 20 * noise(rng);
    touch[i] = (i / 3000) % 3 - 1.0;
  }
  Document doc("hour");
  doc.heading("Campaign", 1);
  doc.paragraph("A one-hour run.");
  doc.table({"run", "IAE"}, {{"adaptive", "1.0"}});
  auto S = [&](const char* name, std::vector<double>& y, Series::Style st = Series::Style::line, bool dashed = false) {
    Series s{.name = name, .x = t, .y = y, .style = st, .dashed = dashed};
    s.samples = n;
    s.source_run = "r";
    s.source_column = name;
    return s;
  };
  std::vector<Marker> marks = {{60, "gap 2.5 deg", ""}};
  doc.figure(Figure{.title = "Pressure",
                    .x_label = "time [s]",
                    .y_label = "pressure [MPa]",
                    .series = {S("p_meas_mpa", p), S("p_ref_mpa", ref, Series::Style::step, true)},
                    .markers = marks,
                    .group = "t",
                    .max_buckets = 1000});
  doc.figure(Figure{.title = "Angles",
                    .x_label = "time [s]",
                    .y_label = "angle [deg]",
                    .series = {S("theta_motor_deg", motor), S("theta_valve_deg", valve)},
                    .markers = marks,
                    .group = "t",
                    .max_buckets = 1000});
  doc.figure(Figure{.title = "Gap",
                    .x_label = "time [s]",
                    .y_label = "gap [deg]",
                    .series = {S("gap_true_deg", gt), S("gap_est_deg", ge)},
                    .markers = marks,
                    .group = "t",
                    .max_buckets = 1000});
  doc.figure(Figure{.title = "Touch",
                    .x_label = "time [s]",
                    .y_label = "state [-]",
                    .series = {S("touch", touch, Series::Style::step)},
                    .markers = marks,
                    .group = "t",
                    .max_buckets = 1000});
  doc.figure(Figure{.title = "Error",
                    .x_label = "time [s]",
                    .y_label = "error [kPa]",
                    .series = {S("err", p)},
                    .markers = marks,
                    .group = "t",
                    .max_buckets = 1000});
  doc.bars(Bars{.title = "stall", .y_label = "s", .categories = {"a", "b"}, .groups = {{"adaptive", {1, 2}}}});
  doc.write(argv[1]);
}
