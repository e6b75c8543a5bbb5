#include "hil/analysis/run_inputs.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>

#include <nlohmann/json.hpp>

#include "hil/units.hpp"
#include "text.hpp"

namespace hil::analysis {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

std::string who(const std::string& source) { return source.empty() ? "" : " (" + source + ")"; }

// A trip's reason and time from run.json (NaN time: none recorded, or no readable run.json).
std::pair<std::string, double> trip_in_run_json(const std::filesystem::path& run_json) {
  std::ifstream in(run_json);
  if (!in) return {"", std::nan("")};
  const auto j = nlohmann::json::parse(in, nullptr, false);
  if (!j.is_object() || !j.contains("trip") || !j["trip"].is_object()) return {"", std::nan("")};
  const auto& t = j["trip"];
  const double at = t.contains("t_s") && t["t_s"].is_number() ? t["t_s"].get<double>() : std::nan("");
  const std::string reason = t.contains("reason") && t["reason"].is_string() ? t["reason"].get<std::string>() : "?";
  return {reason, at};
}

}  // namespace

bool RunInputs::leave_out(std::size_t row, double t_s) {
  bool out = false;
  for (auto& w : left_out) {
    if (!(t_s >= w.t0_s && t_s < w.t1_s)) continue;
    if (w.rows++ == 0) w.first_row = row;
    w.last_row = row;
    out = true;
  }
  rows_left_out_ += out ? 1 : 0;
  return out;
}

void RunInputs::left_out_counts_reset() {
  for (auto& w : left_out) w.first_row = w.last_row = w.rows = 0;
  rows_left_out_ = 0;
}

double RunInputs::gap_at(double t_s) const {
  const auto it = std::upper_bound(gap.begin(), gap.end(), t_s, [](double t, const GapInput& g) { return t < g.t_s; });
  return it == gap.begin() ? std::nan("") : std::prev(it)->gap_rad;
}

std::vector<std::string> RunInputs::notes(std::size_t total_rows) const {
  std::vector<std::string> out;
  for (const auto& w : left_out) {
    const std::string span = std::isfinite(w.t1_s) ? text::instant(w.t0_s) + "-" + text::instant(w.t1_s) + " s"
                                                   : "from " + text::instant(w.t0_s) + " s to the end";
    if (w.rows == 0) {
      out.push_back("no rows in " + span + " (" + w.why + "): nothing left out");
      continue;
    }
    out.push_back("rows " + std::to_string(w.first_row) + "-" + std::to_string(w.last_row) + " (" + span +
                  ") left out of the fit: " + w.why);
  }
  if (rows_left_out_ > 0)
    out.push_back(std::to_string(rows_left_out_) + " of " + std::to_string(total_rows) +
                  " rows left out: the replay runs through them on the logged inputs, the fit and the statistics skip them");
  for (const auto& g : gap) {
    out.push_back(std::isfinite(g.gap_rad)
                      ? "gap " + text::num(units::rad_to_deg(g.gap_rad), 4) + " deg from " + text::instant(g.t_s) + " s" +
                            who(g.source) + ": a known input of the replay, not an effect to find"
                      : "the model's own gap again from " + text::instant(g.t_s) + " s" + who(g.source));
  }
  return out;
}

RunInputs run_inputs_from(const report::RunMarks& marks) {
  RunInputs in;
  in.unreadable = marks.unreadable;
  for (const auto& m : marks.marks) {
    const bool fault = m.kind == "sensor_fault" || m.kind == "drive_fault";
    if (fault && std::isfinite(m.end_s) && m.end_s > m.t_s) {
      in.left_out.push_back({m.t_s, m.end_s, m.label + who(m.source)});
    } else if (m.kind == "trip" || m.kind == "safe_state") {
      // The safe state lasts to the end of the run: what the loop did from there is no test of the plant's model.
      const bool covered = std::any_of(in.left_out.begin(), in.left_out.end(),
                                       [&](const LeftOutWindow& w) { return !std::isfinite(w.t1_s) && w.t0_s <= m.t_s; });
      if (!covered) in.left_out.push_back({m.t_s, kInf, m.label + who(m.source)});
    } else if (m.kind == "gap_change" && m.source == "operator" && std::isfinite(m.value)) {
      in.gap.push_back({m.t_s, units::deg_to_rad(m.value), m.source});
    } else if (m.kind == "gap_programme" && !in.gap.empty()) {
      in.gap.push_back({m.t_s, std::nan(""), m.source});
    }
  }
  return in;
}

RunInputs run_inputs_beside(const std::filesystem::path& data_file) {
  const auto dir = data_file.parent_path().empty() ? std::filesystem::path(".") : data_file.parent_path();
  RunInputs in = run_inputs_from(report::marks_from_events(dir / "events.jsonl", kInf));
  const auto [reason, at] = trip_in_run_json(dir / "run.json");
  const bool have_trip = std::any_of(in.left_out.begin(), in.left_out.end(), [](const LeftOutWindow& w) {
    return w.why.rfind("trip", 0) == 0 || w.why.rfind("safe state", 0) == 0;
  });
  if (std::isfinite(at) && !have_trip) in.left_out.push_back({at, kInf, "trip: " + reason + " (run.json)"});
  return in;
}

}  // namespace hil::analysis
