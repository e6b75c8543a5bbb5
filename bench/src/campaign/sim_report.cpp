#include "sim_report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

#include "hil/palette.hpp"
#include "hil/report/report.hpp"
#include "hil/telemetry_schema.hpp"
#include "hil/units.hpp"

namespace hil::bench {
namespace {

using report::Figure;
using report::Series;

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

using telemetry::Col;

// The time figures' overview: min and max of this many buckets (2000 points over a plot ~1300 px
// wide: every spike drawn). Few enough that an hour's report opens in under 2 s
// (docs/benchmarks.md); a served report fetches every sample of a zoomed window.
constexpr int kOverviewBuckets = 1000;

// A signal's colour from the one palette (common/palette/signals.txt), as the console draws it.
std::string C(std::string_view signal) { return std::string(palette::color(signal)); }

// A telemetry column's decimated series in the run (nullptr: the report does not keep it).
const ReportSeries* find(const RunOutcome& r, telemetry::Col column) {
  for (const auto& s : r.series)
    if (s.name == telemetry::name(column)) return &s;
  return nullptr;
}

Series series(const RunOutcome& r, telemetry::Col name, std::string label, std::string color = "",
              Series::Style style = Series::Style::line, bool dashed = false) {
  const ReportSeries* s = find(r, name);
  Series out;
  out.name = std::move(label);
  if (s) out.x = s->t_s, out.y = s->value, out.samples = s->samples;
  if (s && !r.detail_run.empty()) out.source_run = r.detail_run, out.source_column = s->name;
  out.color = std::move(color);
  out.style = style;
  out.dashed = dashed;
  return out;
}

// Reversals whose window (to the next reversal, or the end) is long enough to compare runs.
bool full_window(const std::vector<ReversalSummary>& rv, std::size_t i, double end_s) {
  const double next = i + 1 < rv.size() ? rv[i + 1].t_s : end_s;
  return next - rv[i].t_s >= 1.0;
}

std::string describe_gap(const Campaign& c) {
  std::string text = "gap " + fmt("%.3g", units::rad_to_deg(c.gap_rad.initial())) + " deg";
  const auto& pts = c.gap_rad.points();
  if (pts.empty()) return text + ", constant";
  if (pts.size() <= 6) {
    for (std::size_t i = 0; i + 1 < pts.size(); i += 2) {
      text += "; " + fmt("%.4g", units::rad_to_deg(pts[i + 1].value)) + " deg at " + fmt("%.4g", pts[i + 1].t_s) + " s";
    }
    return text;
  }
  return text + ", " + std::to_string(pts.size() / 2) + " programmed changes";
}

}  // namespace

void write_sim_report(const Campaign& c, const std::vector<RunOutcome>& runs, const std::filesystem::path& file,
                      const std::string& origin, const std::string& note) {
  report::Document doc(origin + ": " + c.name);
  doc.heading("Campaign " + c.name, 1);
  if (!c.description.empty()) doc.paragraph(c.description);
  if (!note.empty()) doc.paragraph(note);
  doc.paragraph("Plant " + c.plant_file.filename().string() + "; " + fmt("%.6g", c.duration_s) +
                " s at dT = " + fmt("%.3g", c.period_s * 1e3) + " ms; sensor noise " + fmt("%.3g", c.sensor_noise_rms_pa / 1e3) +
                " kPa RMS; seed " + std::to_string(c.seed) + "; " + std::to_string(c.reversals_s.size()) +
                " reference reversals; programmed " + describe_gap(c) + ".");
  // What happened, run by run: a served run's recorded events (what the operator injected, when),
  // else (a simulation) the programme; the plots mark the same.
  std::vector<RunMarks> marks;
  for (const auto& r : runs) marks.push_back(r.marks_recorded ? r.marks : marks_from_programme(c));
  for (std::size_t i = 0; i < runs.size(); ++i) {
    if (!runs[i].marks_recorded) continue;
    const std::string what = describe_marks(marks[i].marks);
    doc.paragraph("What happened in " + runs[i].name + ": " + (what.empty() ? "no operator action, fault or trip" : what) + ".");
    if (!marks[i].unreadable.empty()) doc.note("events skipped: " + marks[i].unreadable, true);
  }

  // Summary metrics, one row per run.
  std::vector<std::vector<std::string>> rows;
  for (const auto& r : runs) {
    const auto& s = r.summary;
    const RunSpec* spec = nullptr;
    for (const auto& rs : c.runs)
      if (rs.name == r.name || r.name.rfind(rs.name + " (", 0) == 0) spec = &rs;  // "adaptive (its folder)"
    const char* comp = !spec ? "?" : ctl::compensation_name(spec->controller.compensation);
    const std::string compensator = !spec ? "?" : spec->controller.compensator;
    rows.push_back({r.name, comp, compensator, fmt("%.4f", s.iae_mpa_s), fmt("%.4f", s.rmse_mpa), fmt("%.3f", s.stall_s_total),
                    fmt("%.1f", 100 * s.stall_fraction),
                    fmt("%.2f", s.reversals.empty() ? 0.0 : double(s.touch_state_changes) / s.reversals.size()),
                    std::to_string(s.compensation_events), fmt("%.3f", s.gap_est_final_deg), fmt("%.3f", s.gap_true_final_deg)});
  }
  doc.heading("Summary");
  doc.table({"run", "compensation", "compensator", "IAE [MPa s]", "RMSE [MPa]", "stall [s]", "stall % of motion",
             "touch changes / reversal", "jumps", "gap est. final [deg]", "gap true final [deg]"},
            rows);
  doc.paragraph(
      "Stall: time the valve stood still while the motor moved (faster than 0.5 deg/s), known only in simulation. "
      "IAE integrates |Pg - Pref| with the true chamber pressure.");

  // Stall per reversal, side by side.
  if (!c.reversals_s.empty() && c.reversals_s.size() <= 200) {
    report::Bars bars;
    bars.title = "Valve stall after each reference reversal";
    bars.y_label = "stall [s]";
    const auto& first = runs.front().summary.reversals;
    for (const auto& rv : first) bars.categories.push_back(fmt("%.4g s", rv.t_s));
    for (const auto& r : runs) {
      std::vector<double> v;
      for (std::size_t i = 0; i < bars.categories.size(); ++i)
        v.push_back(i < r.summary.reversals.size() ? r.summary.reversals[i].stall_s : 0.0);
      bars.groups.emplace_back(r.name, std::move(v));
    }
    doc.bars(bars);
    std::vector<std::string> header{"reversal at [s]", "gap true [deg]"};
    for (const auto& r : runs) header.push_back(r.name + " stall [s]");
    for (const auto& r : runs) header.push_back(r.name + " gap est. [deg]");
    std::vector<std::vector<std::string>> rrows;
    for (std::size_t i = 0; i < first.size(); ++i) {
      std::vector<std::string> row{fmt("%.3f", first[i].t_s) + (full_window(first, i, c.duration_s) ? "" : " (short)"),
                                   fmt("%.3f", first[i].gap_true_deg)};
      for (const auto& r : runs) row.push_back(i < r.summary.reversals.size() ? fmt("%.3f", r.summary.reversals[i].stall_s) : "");
      for (const auto& r : runs)
        row.push_back(i < r.summary.reversals.size() ? fmt("%.3f", r.summary.reversals[i].gap_est_deg) : "");
      rrows.push_back(std::move(row));
    }
    doc.table(header, rrows);
  }

  // Paper-style figures, runs side by side; every time axis zooms together.
  doc.heading("Traces");
  doc.paragraph("Drag to zoom (all time axes follow), double-click to reset, click a legend entry to hide it.");
  Figure overlay{"Pressure, all runs", "time [s]", "pressure [MPa]"};
  overlay.group = "t";
  overlay.max_buckets = kOverviewBuckets;
  overlay.series.push_back(series(runs.front(), Col::p_ref_mpa, "reference", C("p_ref_mpa"), Series::Style::step, true));
  for (const auto& r : runs) overlay.series.push_back(series(r, Col::p_meas_mpa, r.name + " measured"));
  // Recorded events per run (named when there are several); the programme, the same for all, once.
  for (std::size_t i = 0; i < runs.size(); ++i) {
    if (runs[i].marks_recorded)
      report::mark_figure(overlay, marks[i], false, runs.size() > 1 ? runs[i].name + ": " : "");
    else if (i == 0)
      report::mark_figure(overlay, marks[i], false);
  }
  doc.figure(overlay);

  const int n = static_cast<int>(runs.size());
  doc.columns_begin(n);
  for (std::size_t i = 0; i < runs.size(); ++i) {
    const auto& r = runs[i];
    Figure f{r.name + ": pressure vs reference", "time [s]", "pressure [MPa]"};
    report::mark_figure(f, marks[i], true);
    f.group = "t";
    f.max_buckets = kOverviewBuckets;
    f.series = {series(r, Col::p_ref_mpa, "reference", C("p_ref_mpa"), Series::Style::step, true),
                series(r, Col::p_meas_mpa, "measured", C("p_meas_mpa"))};
    doc.figure(f);
  }
  for (std::size_t i = 0; i < runs.size(); ++i) {
    const auto& r = runs[i];
    Figure f{r.name + ": touch state", "time [s]", "touch state Tf [-1, 0, +1]"};
    report::mark_figure(f, marks[i], true);
    f.group = "t";
    f.max_buckets = kOverviewBuckets;
    f.height_px = 180;
    f.series = {series(r, Col::touch_state, "Tf", C("touch_state"), Series::Style::step)};
    doc.figure(f);
  }
  for (std::size_t i = 0; i < runs.size(); ++i) {
    const auto& r = runs[i];
    Figure f{r.name + ": motor vs valve angle", "time [s]", "angle [deg]"};
    report::mark_figure(f, marks[i], true);
    f.group = "t";
    f.max_buckets = kOverviewBuckets;
    f.series = {series(r, Col::theta_cmd_deg, "command", C("theta_cmd_deg"), Series::Style::line, true),
                series(r, Col::theta_motor_deg, "motor", C("theta_motor_deg")),
                series(r, Col::theta_valve_deg, "valve", C("theta_valve_deg"))};
    // A real drive's shaped target, where it is not the command (a rig with target shaping).
    const ReportSeries* cmd = find(r, Col::theta_cmd_deg);
    const ReportSeries* target = find(r, Col::theta_target_deg);
    if (cmd && target && target->value != cmd->value)
      f.series.push_back(series(r, Col::theta_target_deg, "drive target", C("theta_target_deg")));
    doc.figure(f);
  }
  for (std::size_t i = 0; i < runs.size(); ++i) {
    const auto& r = runs[i];
    Figure f{r.name + ": gap estimate vs true gap", "time [s]", "gap [deg]"};
    report::mark_figure(f, marks[i], true);
    f.group = "t";
    f.max_buckets = kOverviewBuckets;
    f.height_px = 200;
    f.series = {series(r, Col::gap_true_deg, "true gap", C("gap_true_deg"), Series::Style::step, true),
                series(r, Col::gap_est_deg, "estimate", C("gap_est_deg"), Series::Style::step)};
    doc.figure(f);
  }
  doc.columns_end();

  // With many reversals, the estimate at each one against the truth says more than the trace.
  if (c.reversals_s.size() > 20) {
    Figure f{"Gap estimate at each reversal", "true gap [deg]", "estimate / true gap [-]"};
    f.hlines = {{1.2, "+20 %"}, {0.8, "-20 %"}, {1.0, "exact", false}};
    for (const auto& r : runs) {
      Series s;
      s.name = r.name;
      s.style = Series::Style::points;
      for (std::size_t i = 2; i < r.summary.reversals.size(); ++i) {
        const auto& rv = r.summary.reversals[i];
        if (rv.gap_true_deg <= 0) continue;
        s.x.push_back(rv.gap_true_deg);
        s.y.push_back(rv.gap_est_deg / rv.gap_true_deg);
      }
      f.series.push_back(std::move(s));
    }
    doc.figure(f);
  }
  doc.write(file);
}

}  // namespace hil::bench
