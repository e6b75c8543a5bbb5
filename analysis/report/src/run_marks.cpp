#include "hil/report/run_marks.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "hil/palette.hpp"
#include "hil/report/report.hpp"

namespace hil::report {
namespace {

using nlohmann::json;

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

double number(const json& e, const char* key) {
  const auto it = e.find(key);
  return it != e.end() && it->is_number() ? it->get<double>() : std::nan("");
}

std::string text(const json& e, const char* key) {
  const auto it = e.find(key);
  return it != e.end() && it->is_string() ? it->get<std::string>() : "";
}

std::string label_of(const std::string& kind, const json& e) {
  if (kind == "gap_change") {
    const double g = number(e, "gap_deg");
    return std::isfinite(g) ? "gap " + fmt("%.4g", g) + " deg" : "gap change";
  }
  if (kind == "gap_programme") return "gap back to programme";
  if (kind == "sensor_fault") {
    const std::string mode = text(e, "mode");
    std::string l = "sensor " + (mode.empty() ? std::string("fault") : mode);
    if (const double v = number(e, "held_mpa"); std::isfinite(v)) l += " " + fmt("%.4g", v) + " MPa";
    if (const double v = number(e, "bias_kpa"); std::isfinite(v)) l += " " + fmt("%.4g", v) + " kPa";
    if (const double v = number(e, "rms_kpa"); std::isfinite(v)) l += " " + fmt("%.4g", v) + " kPa rms";
    return l;
  }
  if (kind == "drive_fault") return "drive ignores commands";
  if (kind == "rig_fault") return "rig silent";
  if (kind == "faults_cleared") return "faults cleared";
  if (kind == "fault_expired") return text(e, "fault").empty() ? "fault expired" : text(e, "fault") + " fault expired";
  if (kind == "trip") return "trip: " + (text(e, "reason").empty() ? std::string("?") : text(e, "reason"));
  if (kind == "safe_state") return "safe state";
  if (kind == "stopped") return "stopped";
  if (kind == "stop_request") return "stop requested";
  if (kind == "abort_request") return "abort";
  return "";
}

}  // namespace

std::string mark_label(const json& e) { return e.is_object() ? label_of(text(e, "kind"), e) : ""; }

namespace {

bool is_fault(const std::string& kind) { return kind == "sensor_fault" || kind == "drive_fault"; }

}  // namespace

RunMarks marks_from_events(const std::filesystem::path& events_jsonl, double end_s) {
  RunMarks out;
  std::ifstream in(events_jsonl);
  if (!in) return out;
  std::string line;
  std::size_t line_no = 0, bad = 0;
  // The open window of each fault (sensor, drive): an index into out.marks, or none.
  const std::size_t none = static_cast<std::size_t>(-1);
  std::size_t open_sensor = none, open_drive = none;
  const auto close = [&](std::size_t& open, double t) {
    if (open != none && !std::isfinite(out.marks[open].end_s)) out.marks[open].end_s = t;
    open = none;
  };
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty()) continue;
    const json e = json::parse(line, nullptr, false);
    const double t = e.is_object() ? number(e, "t_s") : std::nan("");
    if (!e.is_object()) {
      if (bad++ == 0) out.unreadable = events_jsonl.string() + ":" + std::to_string(line_no) + ": not a JSON object";
      continue;
    }
    if (!std::isfinite(t)) continue;  // server-side records without a loop time (a request's receipt)
    const std::string kind = text(e, "kind");
    const std::string label = label_of(kind, e);
    if (label.empty()) continue;
    // A fault's window: its duration, else until it expires, is cleared or replaced.
    if (kind == "sensor_fault" || kind == "faults_cleared" || (kind == "fault_expired" && text(e, "fault") != "drive"))
      close(open_sensor, t);
    if (kind == "drive_fault" || kind == "faults_cleared" || (kind == "fault_expired" && text(e, "fault") == "drive"))
      close(open_drive, t);
    RunMark m{t, std::nan(""), label, kind, text(e, "source"), kind == "gap_change" ? number(e, "gap_deg") : std::nan("")};
    const bool off = e.contains("on") && e["on"].is_boolean() && !e["on"].get<bool>();
    if (is_fault(kind) && text(e, "mode") != "none" && !off) {
      const double d = number(e, "duration_s");
      m.end_s = std::isfinite(d) && d > 0 ? t + d : std::nan("");
      (kind == "sensor_fault" ? open_sensor : open_drive) = out.marks.size();
    }
    out.marks.push_back(std::move(m));
  }
  close(open_sensor, end_s);
  close(open_drive, end_s);
  if (bad > 1) out.unreadable += " (and " + std::to_string(bad - 1) + " more lines)";
  std::stable_sort(out.marks.begin(), out.marks.end(), [](const RunMark& a, const RunMark& b) { return a.t_s < b.t_s; });
  return out;
}

std::string describe_marks(const std::vector<RunMark>& marks, std::size_t max_items) {
  // Appended piece by piece: GCC 12 warns (-Wrestrict, a false positive) on "literal" + temporary.
  std::string s;
  for (std::size_t i = 0; i < marks.size() && i < max_items; ++i) {
    const auto& m = marks[i];
    if (!s.empty()) s += "; ";
    s += m.label;
    if (std::isfinite(m.end_s)) {
      s += ' ';
      s += fmt("%.3f", m.t_s);
      s += '-';
      s += fmt("%.3f", m.end_s);
    } else {
      s += " at ";
      s += fmt("%.3f", m.t_s);
    }
    s += " s";
  }
  if (marks.size() > max_items) {
    s += "; and ";
    s += std::to_string(marks.size() - max_items);
    s += " more";
  }
  return s;
}

namespace {

// The one legend entry of a figure's fault windows names what was shaded ("sensor stuck 1.001 MPa;
// dropout"), the first few of them, so a reader need not hover each band to learn it.
std::string windows_legend(const RunMarks& marks, const std::string& prefix) {
  constexpr std::size_t kNamed = 3;
  std::vector<std::string> labels;
  for (const auto& e : marks.marks)
    if (std::isfinite(e.end_s) && std::find(labels.begin(), labels.end(), e.label) == labels.end()) labels.push_back(e.label);
  std::string legend = prefix;
  for (std::size_t i = 0; i < labels.size() && i < kNamed; ++i) legend.append(i ? "; " : "").append(labels[i]);
  if (labels.size() > kNamed)
    legend.append("; and ").append(std::to_string(labels.size() - kNamed)).append(" more fault windows");
  return legend;
}

}  // namespace

void mark_figure(Figure& figure, const RunMarks& marks, bool with_bands, const std::string& prefix) {
  const std::string line(palette::color("event")), window(palette::color("fault_window"));
  const std::string legend = with_bands ? windows_legend(marks, prefix) : std::string();
  for (const auto& e : marks.marks) {
    figure.markers.push_back({e.t_s, prefix + e.label, line});
    if (with_bands && std::isfinite(e.end_s)) figure.bands.push_back({e.t_s, e.end_s, prefix + e.label, window, legend});
  }
}

}  // namespace hil::report
