// A finished sweep's outputs: sweep.csv, sweep.json, report.html (robustness maps, pass/fail, the
// worst points) and the worst points' campaigns to reproduce them with `hilbench sim`.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>

#include <spdlog/spdlog.h>

#include "hil/bench/campaign/sweep.hpp"
#include "hil/line_file.hpp"
#include "hil/report/report.hpp"
#include "sim_report.hpp"
#include "sweep_words.hpp"

namespace hil::bench {
namespace {

using json = nlohmann::json;

constexpr std::size_t kWorstPoints = 10;
// Of those, how many get their campaign's report (a campaign run each, about a second for the
// shipped ones): the rest have the command that makes it.
constexpr std::size_t kTracedPoints = 3;

std::string unit_suffix(const std::string& unit) { return unit.empty() ? "" : " " + unit; }

std::string number_text(double v) {
  if (!std::isfinite(v)) return "nan";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string q = "\"";
  for (char ch : s) q += ch == '"' ? std::string("\"\"") : std::string(1, ch);
  return q + "\"";
}

// An axis value for JSON: a number when the whole text is one.
json value_json(const std::string& s) {
  double v = 0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  if (!s.empty() && r.ec == std::errc() && r.ptr == s.data() + s.size() && std::isfinite(v)) return v;
  return s;
}

json metric_json(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

std::size_t index_of(const std::vector<std::string>& names, const std::string& name) {
  return static_cast<std::size_t>(std::find(names.begin(), names.end(), name) - names.begin());
}

std::string bound_text(const SweepBound& b) {
  std::string s = b.metric;
  if (b.min) s += " >= " + number_text(*b.min);
  if (b.min && b.max) s += " and";
  if (b.max) s += " <= " + number_text(*b.max);
  return s;
}

// The run a metric belongs to: "adaptive_paper.stall_vs_none" -> "adaptive_paper".
std::string run_of(const std::string& metric) { return metric.substr(0, metric.rfind('.')); }

// Whether point `metrics` fails for `run`: a threshold on one of the run's metrics missed, or a
// check of the run's campaign failed. The paper's observer failing never fails the robust one's.
bool run_fails(const SweepPlan& plan, const std::vector<std::string>& names, const std::vector<double>& metrics,
               const std::string& run) {
  for (const auto& t : plan.thresholds) {
    if (run_of(t.metric) != run) continue;
    const std::size_t i = index_of(names, t.metric);
    if (!MapBound{t.min, t.max}.holds(i < metrics.size() ? metrics[i] : std::nan(""))) return true;
  }
  const std::size_t c = index_of(names, run + ".checks_failed");
  return c < metrics.size() && std::isfinite(metrics[c]) && metrics[c] != 0;
}

std::string axis_title(const SweepPlan& plan, const std::string& path) {
  for (const auto& a : plan.axes)
    if (a.path == path) return axis_words(plan, a).title();
  return path;
}

// A heatmap of one metric over two axes, coloured against the map's own threshold (its `min`/
// `max`, else the sweep's threshold of the metric; without one, by the value's own range), and in
// every cell how many of its points fail for the metric's run.
void add_map(report::Document& doc, const SweepPlan& plan, const SweepMap& map, const std::map<long, std::vector<double>>& rows) {
  const auto names = plan.metric_names();
  std::vector<std::string> paths;
  for (const auto& a : plan.axes) paths.push_back(a.path);
  const std::size_t xi = index_of(paths, map.x), yi = index_of(paths, map.y), mi = index_of(names, map.metric);
  const auto& xs = plan.axes[xi].values;
  const auto& ys = plan.axes[yi].values;
  const std::string run = run_of(map.metric);
  const MapBound bound = map_bound(plan, map);
  report::Heatmap h;
  h.x_label = axis_title(plan, map.x);
  h.y_label = axis_title(plan, map.y);
  h.x_ticks = xs;
  h.y_ticks = ys;
  std::vector<std::vector<std::vector<double>>> cell(ys.size(), std::vector<std::vector<double>>(xs.size()));
  std::vector<std::vector<long>> failing(ys.size(), std::vector<long>(xs.size(), 0));  // points that fail, per cell
  for (const auto& [p, metrics] : rows) {
    const auto& values = plan.points[static_cast<std::size_t>(p)];
    bool in_slice = true;
    for (const auto& [path, v] : map.slice) in_slice = in_slice && values[index_of(paths, path)] == v;
    if (!in_slice) continue;
    const std::size_t x = index_of(xs, values[xi]), y = index_of(ys, values[yi]);
    if (x >= xs.size() || y >= ys.size()) continue;
    cell[y][x].push_back(metrics[mi]);
    const bool fails = (bound.any() && !bound.holds(metrics[mi])) || run_fails(plan, names, metrics, run);
    if (fails) ++failing[y][x];
  }
  h.values.assign(ys.size(), std::vector<double>(xs.size(), std::numeric_limits<double>::quiet_NaN()));
  h.notes.assign(ys.size(), std::vector<std::string>(xs.size()));
  if (bound.any()) h.marked.assign(ys.size(), std::vector<bool>(xs.size(), false));
  for (std::size_t y = 0; y < ys.size(); ++y) {
    for (std::size_t x = 0; x < xs.size(); ++x) {
      double sum = 0, lo = INFINITY, hi = -INFINITY;
      long n = 0;
      for (double v : cell[y][x]) {
        if (!std::isfinite(v)) continue;
        sum += v;
        lo = std::min(lo, v);
        hi = std::max(hi, v);
        ++n;
      }
      if (n > 0) h.values[y][x] = map.reduce == "max" ? hi : map.reduce == "min" ? lo : sum / static_cast<double>(n);
      if (bound.any()) h.marked[y][x] = !bound.holds(h.values[y][x]);
      h.notes[y][x] = std::to_string(failing[y][x]) + " of " + std::to_string(cell[y][x].size()) + " fail";
    }
  }
  std::string others;
  for (const auto& a : plan.axes) {
    if (a.path == map.x || a.path == map.y) continue;
    const auto s = std::find_if(map.slice.begin(), map.slice.end(), [&](const auto& kv) { return kv.first == a.path; });
    const std::string title = axis_words(plan, a).title();
    others += (others.empty() ? "" : ", ") + title + (s != map.slice.end() ? " = " + s->second : " (" + map.reduce + ")");
  }
  if (plan.samples > 1) others += (others.empty() ? "" : ", ") + std::string("samples (") + map.reduce + ")";
  h.title = map.metric;
  h.value_label = others.empty() ? "" : "over " + others;
  h.pass_min = bound.min, h.pass_max = bound.max;  // coloured by its own pass/fail, not the point's
  doc.heatmap(h);
  SweepBound b{map.metric, bound.min, bound.max};
  doc.paragraph(std::string(bound.any() ? "Marked x: the cell's value fails " + bound_text(b) + ". "
                                        : "No threshold for " + map.metric + ": coloured by its range. ") +
                "Under each value: how many of the cell's points fail for the run " + run + " (" +
                (bound.any() ? map.metric + " beyond its threshold, " : "") + run +
                "'s thresholds, or a check of its campaign).");
}

}  // namespace

std::string sweep_csv_header(const SweepPlan& plan) {
  std::string s = "point";
  for (const auto& a : plan.axes) (s += ',') += csv_field(a.path);
  for (const auto& m : plan.metric_names()) (s += ',') += csv_field(m);
  return s + ",pass\n";
}

std::string sweep_csv_row(const SweepPlan& plan, long p, const std::vector<double>& metrics) {
  std::string s = std::to_string(p);
  for (const auto& v : plan.points.at(static_cast<std::size_t>(p))) (s += ',') += csv_field(v);
  for (double v : metrics) (s += ',') += number_text(v);
  return s + (point_passes(plan, metrics) ? ",pass\n" : ",fail\n");
}

namespace {

// Why a point fails, in words: each threshold it misses ("adaptive.stall_vs_none = 0.61 > 0.5") and
// each run with failed checks of its campaign ("adaptive: 3 checks failed", `hilbench sim` on the
// point's campaign names them).
std::string failing_text(const SweepPlan& plan, const std::vector<std::string>& names, const std::vector<double>& metrics) {
  std::string out;
  const auto add = [&](const std::string& s) { out += (out.empty() ? "" : "; ") + s; };
  for (const auto& t : plan.thresholds) {
    const std::size_t i = index_of(names, t.metric);
    const double v = i < metrics.size() ? metrics[i] : std::numeric_limits<double>::quiet_NaN();
    if (!std::isfinite(v)) add(t.metric + " unknown");
    if (t.max && v > *t.max) add(t.metric + " = " + number_text(v) + " > " + number_text(*t.max));
    if (t.min && v < *t.min) add(t.metric + " = " + number_text(v) + " < " + number_text(*t.min));
  }
  static constexpr std::string_view kChecksFailed = ".checks_failed";
  for (std::size_t i = 0; i < names.size() && i < metrics.size(); ++i) {
    const std::string& n = names[i];
    if (n.size() > kChecksFailed.size() && n.compare(n.size() - kChecksFailed.size(), kChecksFailed.size(), kChecksFailed) == 0 &&
        metrics[i] != 0)
      add(n.substr(0, n.size() - kChecksFailed.size()) + ": " + number_text(metrics[i]) + " checks failed");
  }
  return out;
}

}  // namespace

SweepOutputs write_sweep_outputs(const std::filesystem::path& dir, const SweepPlan& plan) {
  const auto rows = read_rows(dir, plan);
  const long missing = plan.size() - static_cast<long>(rows.size());
  if (missing > 0) return {missing, 0, {}};
  const auto names = plan.metric_names();

  std::vector<bool> pass(static_cast<std::size_t>(plan.size()));
  long passed = 0;
  std::string csv = sweep_csv_header(plan);
  json points = json::array();
  for (const auto& [p, metrics] : rows) {
    pass[static_cast<std::size_t>(p)] = point_passes(plan, metrics);
    passed += pass[static_cast<std::size_t>(p)] ? 1 : 0;
    csv += sweep_csv_row(plan, p, metrics);
    json values = json::object(), m = json::object();
    for (std::size_t i = 0; i < plan.axes.size(); ++i)
      values[plan.axes[i].path] = value_json(plan.points[static_cast<std::size_t>(p)][i]);
    for (std::size_t i = 0; i < names.size(); ++i) m[names[i]] = metric_json(metrics[i]);
    points.push_back({{"point", p}, {"values", values}, {"metrics", m}, {"pass", pass[static_cast<std::size_t>(p)]}});
  }
  json thresholds = json::object();
  for (const auto& t : plan.thresholds) {
    json b = json::object();
    if (t.min) b["min"] = *t.min;
    if (t.max) b["max"] = *t.max;
    thresholds[t.metric] = b;
  }
  std::vector<std::string> paths;
  for (const auto& a : plan.axes) paths.push_back(a.path);
  const json out = {{"name", plan.name},       {"description", plan.description},
                    {"runs", plan.runs},       {"seed", plan.seed},
                    {"samples", plan.samples}, {"axes", paths},
                    {"metrics", names},        {"thresholds", thresholds},
                    {"passed", passed},        {"failed", plan.size() - passed},
                    {"points", points}};

  // The worst points: the largest values of worst_by (a metric that is not a number counts as
  // worst), ties by point; each one's campaign written to reproduce it alone.
  const std::size_t wi = index_of(names, plan.worst_by);
  std::vector<long> order;
  for (const auto& [p, m] : rows) order.push_back(p);
  auto worse = [&](long a, long b) {
    const double va = rows.at(a)[wi], vb = rows.at(b)[wi];
    const bool na = !std::isfinite(va), nb = !std::isfinite(vb);
    if (na != nb) return na;
    if (!na && va != vb) return va > vb;
    return a < b;
  };
  const std::size_t n_worst = std::min(kWorstPoints, order.size());
  std::partial_sort(order.begin(), order.begin() + static_cast<long>(n_worst), order.end(), worse);
  order.resize(n_worst);

  report::Document doc("Sweep " + plan.name);
  if (!plan.description.empty()) doc.paragraph(plan.description);
  std::string thresholds_text;
  for (const auto& t : plan.thresholds) thresholds_text += (thresholds_text.empty() ? "" : "; ") + bound_text(t);
  doc.paragraph(std::to_string(plan.size()) + " points (" + std::to_string(plan.size() / plan.samples) + " grid cells x " +
                std::to_string(plan.samples) + " samples), runs: " + [&] {
                  std::string r;
                  for (const auto& x : plan.runs) r += (r.empty() ? "" : ", ") + x;
                  return r;
                }());
  doc.note(std::to_string(passed) + " points pass, " + std::to_string(plan.size() - passed) + " fail" +
               (thresholds_text.empty() ? " (no thresholds set)" : " (" + thresholds_text + ")"),
           passed < plan.size());
  // Per run: a point's verdict mixes every run's thresholds (the paper observer's fails the
  // point where the robust one passes); this says how each run fares on its own.
  for (const auto& r : plan.runs) {
    std::string why;
    for (const auto& t : plan.thresholds)
      if (run_of(t.metric) == r) why += (why.empty() ? "" : "; ") + bound_text(t);
    const bool has_checks = index_of(names, r + ".checks_failed") < names.size();
    long run_passed = 0;
    for (const auto& [p, metrics] : rows) run_passed += run_fails(plan, names, metrics, r) ? 0 : 1;
    doc.paragraph("Run " + r + ": " + std::to_string(run_passed) + " of " + std::to_string(plan.size()) + " points pass (" +
                  (why.empty() ? "no threshold" : why) + (has_checks ? ", and its campaign's checks" : "") + ").");
  }
  for (const auto& map : plan.maps) add_map(doc, plan, map, rows);
  doc.heading("Worst points by " + plan.worst_by);
  std::vector<std::string> header{"point"};
  for (const auto& a : plan.axes) header.push_back(axis_words(plan, a).title());
  header.insert(header.end(), {plan.worst_by, "pass", "fails on", "reproduce"});
  std::vector<std::vector<std::string>> table;
  for (long p : order) {
    std::vector<std::string> row{std::to_string(p)};
    for (const auto& v : plan.points[static_cast<std::size_t>(p)]) row.push_back(v);
    row.push_back(number_text(rows.at(p)[wi]));
    row.push_back(pass[static_cast<std::size_t>(p)] ? "pass" : "fail");
    row.push_back(failing_text(plan, names, rows.at(p)));
    row.push_back("hilbench sim " + (dir / "points" / std::to_string(p) / "campaign.yaml").string());
    table.push_back(std::move(row));
  }
  doc.table(header, table);
  doc.paragraph(
      "Metrics per run: iae_mpa_s (integral of |Pg - Pref|), stall_s_per_reversal (mean valve stall over the reference "
      "reversals), stall_vs_none (that over the none run's), touch_changes_per_reversal, gap_error_deg (mean |gap estimate - "
      "true gap| at reversals 2..n, deg), interlock_trips (debounced over/underpressure trips of the bench's default safety "
      "limits on the measured pressure; the simulation itself runs without interlocks), checks_failed (the campaign's "
      "checks that failed on the run: a point with one fails; `hilbench sim` on the point's campaign names them).");

  for (long p : order) {
    const auto folder = dir / "points" / std::to_string(p);
    std::filesystem::create_directories(folder);
    const PointYaml y = point_yaml(plan, p);
    replace_file(folder / "campaign.yaml", "# sweep " + plan.name + ", point " + std::to_string(p) + "\n" + y.campaign);
    replace_file(folder / "plant.yaml", y.plant);
  }
  // The three outputs are one result: all replaced or none (else a full disk could leave a
  // new sweep.csv beside no sweep.json, and `--status` would call that "outputs written"). They are
  // written before the worst points' traces, which are a convenience (about 0.7 MB a report):
  // traces that do not fit on the disk must not cost the results.
  const std::size_t n_traced = std::min(kTracedPoints, order.size());
  {
    hil::report::Document first = doc;
    if (n_traced > 0) {
      first.heading("Traces of the worst points", 3);
      first.paragraph("Not written yet: `hilbench sim points/P/campaign.yaml` makes the trace of point P.");
    }
    const std::string json_text = out.dump(1) + "\n", html = first.html();
    const FileText outputs[] = {{dir / "sweep.csv", {csv}}, {dir / "sweep.json", {json_text}}, {dir / "report.html", {html}}};
    replace_files(outputs);
  }
  if (n_traced == 0) return {0, passed, order};
  // The worst few points' traces, pre-rendered: the campaign report of each (the figures of
  // `hilbench sim`, no telemetry files), then the report again with their links.
  doc.heading("Traces of the worst points", 3);
  for (std::size_t i = 0; i < n_traced; ++i) {
    const long p = order[i];
    const auto folder = dir / "points" / std::to_string(p);
    const Campaign c = PointMaker(plan).campaign(p);
    SimOptions options;
    options.out_dir = folder;
    options.telemetry = false;
    options.progress = false;
    std::string where;
    for (std::size_t a = 0; a < plan.axes.size(); ++a)
      where += (where.empty() ? "" : ", ") + axis_words(plan, plan.axes[a]).label + " " +
               plan.points[static_cast<std::size_t>(p)][a] + unit_suffix(axis_words(plan, plan.axes[a]).unit);
    const std::string why = failing_text(plan, names, rows.at(p));
    const std::string title = "Point " + std::to_string(p) + " (" + where + (why.empty() ? "" : "; " + why) + "): ";
    // One that cannot be written (a full disk) is said in the report and the log; the point's
    // campaign.yaml above gives it again with `hilbench sim`.
    try {
      run_campaign(c, options);
    } catch (const Cancelled&) {
      throw;
    } catch (const std::exception& e) {
      const std::string reason = "its trace was not written (" + std::string(e.what()) + "); `hilbench sim " +
                                 (folder / "campaign.yaml").string() + "` makes it";
      spdlog::warn("sweep {}: point {}: {}", plan.name, p, reason);
      doc.paragraph(title + reason);
      continue;
    }
    const std::string href = "points/" + std::to_string(p) + "/" + c.name + "/report.html";
    doc.link(title, href, href);
  }
  try {
    replace_file(dir / "report.html", doc.html());
  } catch (const std::exception& e) {
    spdlog::warn("sweep {}: report.html keeps no links to the traces ({})", plan.name, e.what());
  }
  return {0, passed, order};
}

}  // namespace hil::bench
