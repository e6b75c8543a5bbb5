// Report contents shaped like the real ones, for the report suites: a 3-run campaign (18 s at
// 1 kHz each) as `hilbench sim` writes it, and a model-validation page with every figure kind.
#pragma once

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "hil/report/report.hpp"

namespace hil::test {

// One simulated run: references, pressure, backlash angles, gap estimate, at `rate_hz`.
struct CampaignRun {
  std::vector<double> t_s, p_ref_mpa, p_mpa, touch, motor_deg, valve_deg, gap_true_deg, gap_est_deg;
};

inline CampaignRun simulate_run(int run, double duration_s = 18.0, double rate_hz = 1000.0) {
  CampaignRun r;
  const auto n = static_cast<std::size_t>(duration_s * rate_hz);
  std::mt19937 rng(42 + run);
  std::normal_distribution<double> noise(0.0, 0.01);
  double p = 2.0, valve = 0.0, est = 1.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) / rate_hz;
    const double ref = t < 4 ? 2.0 : t < 10 ? 4.0 + 0.2 * run : t < 14 ? 3.0 : 3.5;
    const double gap = t < 9 ? 2.0 : 2.0 + 0.5 * (run + 1);
    const double motor = 20 + 6 * std::sin(0.9 * t + run) + 3 * (ref - 2.0);
    // Backlash: the valve follows the motor only once the gap is taken up on either side.
    if (motor - valve > gap / 2) valve = motor - gap / 2;
    if (valve - motor > gap / 2) valve = motor + gap / 2;
    p += (ref - p) * (1.0 / rate_hz) * 3.0;
    est += (gap - est) * (1.0 / rate_hz) * 0.8;
    const double touch = std::abs(motor - valve) >= gap / 2 - 1e-9 ? (motor > valve ? 2 : 1) : 0;
    r.t_s.push_back(t);
    r.p_ref_mpa.push_back(ref);
    r.p_mpa.push_back(p + noise(rng) + (i % 3000 == 1500 ? 0.4 : 0.0));  // rare spikes
    r.touch.push_back(touch);
    r.motor_deg.push_back(motor);
    r.valve_deg.push_back(valve);
    r.gap_true_deg.push_back(gap);
    r.gap_est_deg.push_back(est);
  }
  return r;
}

// The campaign report of `hilbench sim`: runs side by side, one row per quantity.
inline std::vector<CampaignRun> simulate_campaign(int runs = 3, double duration_s = 18.0) {
  std::vector<CampaignRun> data;
  for (int k = 0; k < runs; ++k) data.push_back(simulate_run(k, duration_s));
  return data;
}

inline void add_campaign(report::Document& doc, const std::vector<CampaignRun>& data) {
  using report::Figure;
  using report::Series;
  const int runs = static_cast<int>(data.size());
  doc.heading("Campaign: step references, gap change at 9 s");
  doc.paragraph("Each column is one run; all time plots share their x zoom.");
  doc.columns_begin(runs);
  for (int k = 0; k < runs; ++k) doc.heading("Run " + std::to_string(k + 1), 3);
  for (int k = 0; k < runs; ++k) {
    const auto& r = data[static_cast<std::size_t>(k)];
    doc.figure(Figure{
        .title = "Pressure",
        .x_label = "time [s]",
        .y_label = "pressure [MPa]",
        .series = {Series{.name = "measured", .x = r.t_s, .y = r.p_mpa},
                   Series{.name = "reference", .x = r.t_s, .y = r.p_ref_mpa, .style = Series::Style::step, .dashed = true}},
        .group = "campaign"});
  }
  for (int k = 0; k < runs; ++k) {
    const auto& r = data[static_cast<std::size_t>(k)];
    doc.figure(Figure{.title = "Touch state (0 free, 1 closing side, 2 opening side)",
                      .x_label = "time [s]",
                      .y_label = "state",
                      .series = {Series{.name = "touch", .x = r.t_s, .y = r.touch, .style = Series::Style::step}},
                      .group = "campaign",
                      .height_px = 150});
  }
  for (int k = 0; k < runs; ++k) {
    const auto& r = data[static_cast<std::size_t>(k)];
    doc.figure(Figure{
        .title = "Motor vs valve angle",
        .x_label = "time [s]",
        .y_label = "angle [deg]",
        .series = {Series{.name = "motor", .x = r.t_s, .y = r.motor_deg}, Series{.name = "valve", .x = r.t_s, .y = r.valve_deg}},
        .group = "campaign"});
  }
  for (int k = 0; k < runs; ++k) {
    const auto& r = data[static_cast<std::size_t>(k)];
    doc.figure(
        Figure{.title = "Gap estimate vs true gap",
               .x_label = "time [s]",
               .y_label = "gap [deg]",
               .series = {Series{.name = "estimate", .x = r.t_s, .y = r.gap_est_deg},
                          Series{.name = "true", .x = r.t_s, .y = r.gap_true_deg, .style = Series::Style::step, .dashed = true}},
               .group = "campaign"});
  }
  doc.columns_end();
  std::vector<std::vector<std::string>> rows;
  for (int k = 0; k < runs; ++k) {
    rows.push_back({"run " + std::to_string(k + 1), std::to_string(0.012 + 0.003 * k), "1.85", std::to_string(3 + k),
                    k == 2 ? "FAIL" : "pass"});
  }
  doc.heading("Metrics", 3);
  doc.table({"run", "RMS error [MPa]", "settling time [s]", "overshoots", "verdict"}, rows);
}

}  // namespace hil::test
