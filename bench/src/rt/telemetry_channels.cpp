#include "hil/bench/rt/telemetry_channels.hpp"

#include <cmath>
#include <ctime>
#include <limits>

#include <nlohmann/json.hpp>

#include "hil/csv_writer.hpp"

namespace hil::bench {
namespace {

using nlohmann::json;
using telemetry::Col;

constexpr std::uint32_t kEventsChannel = 5;

}  // namespace

const std::vector<TelemetryChannel>& telemetry_channels() {
  static const std::vector<TelemetryChannel> kChannels = [] {
    std::vector<TelemetryChannel> c = {
        {1, "/hilbench/pressure", {Col::t_s, Col::p_ref_mpa, Col::p_meas_mpa, Col::p_chamber_mpa}},
        {2,
         "/hilbench/angles",
         {Col::t_s, Col::theta_cmd_deg, Col::theta_target_deg, Col::theta_motor_deg, Col::theta_valve_deg}},
        {3,
         "/hilbench/observer",
         {Col::t_s, Col::touch_state, Col::motion_intention, Col::gap_est_deg, Col::gap_true_deg, Col::comp_deg}},
        {4, "/hilbench/loop", {Col::t_s, Col::wake_latency_us, Col::compute_us, Col::loop_flags}},
        {kEventsChannel, "/hilbench/events", {}},
    };
    c.push_back(telemetry_channel(ColumnSet::all));
    return c;
  }();
  return kChannels;
}

const TelemetryChannel& events_channel() { return telemetry_channels()[kEventsChannel - 1]; }

TelemetryChannel telemetry_channel(ColumnSet set) {
  TelemetryChannel c{6, std::string(telemetry::kTopic), {}};
  const std::size_t n = set == ColumnSet::sim ? telemetry::kSimColumns : telemetry::kLoopColumns;
  for (std::size_t k = 0; k < n; ++k) {
    if (set == ColumnSet::measured && telemetry::kColumns[k].truth_only) continue;
    c.columns.push_back(static_cast<Col>(k));
  }
  return c;
}

std::string schema_name(const TelemetryChannel& c) { return "hilbench" + c.topic.substr(c.topic.rfind('/')); }

std::string schema_json(const TelemetryChannel& c) {
  json properties = json::object();
  if (c.columns.empty()) {
    properties["kind"] = {{"type", "string"}, {"description", "the event (events.jsonl): gap_change, trip, safe_state, ..."}};
    properties["type"] = {{"type", "string"}, {"description", "the server's notice (live stream): run_start, run_end, ..."}};
    properties["t_s"] = {{"type", "number"}, {"description", "the run's time of the event"}, {"unit", "s"}};
    properties["utc"] = {{"type", "string"}, {"description", "when it was written (UTC, ISO 8601)"}};
    return json{{"type", "object"},
                {"properties", properties},
                {"anyOf", json::array({{{"required", {"kind"}}}, {{"required", {"type"}}}})}}
        .dump();
  }
  for (const Col col : c.columns) {
    const std::string unit(telemetry::unit(col));
    json p = {{"type", {"number", "null"}},
              {"description", std::string(telemetry::column(col).meaning) + (unit.empty() ? "" : " [" + unit + "]")}};
    if (!unit.empty()) p["unit"] = unit;
    properties[std::string(telemetry::name(col))] = std::move(p);
  }
  return json{{"type", "object"}, {"properties", properties}}.dump();
}

std::string payload_json(const TelemetryChannel& c, const TelemetryRow& row) {
  std::string out;
  out.reserve(24 * c.columns.size() + 2);
  out.push_back('{');
  char cell[64];
  for (const Col col : c.columns) {
    if (out.size() > 1) out.push_back(',');
    out.push_back('"');
    out.append(telemetry::name(col));
    out.append("\":");
    const double v = row[telemetry::index(col)];
    if (std::isfinite(v))
      out.append(cell, format_fixed(cell, cell + sizeof cell, v, telemetry::column(col).decimals));
    else
      out.append("null");
  }
  out.push_back('}');
  return out;
}

std::uint64_t row_time_ns(double t_s) {
  if (!(t_s > 0)) return 0;
  if (t_s >= 1.8e10) return std::numeric_limits<std::uint64_t>::max();  // 570 years: beyond any run
  const double scale = std::pow(10.0, telemetry::column(Col::t_s).decimals);
  return static_cast<std::uint64_t>(std::llround(std::round(t_s * scale) / scale * 1e9));
}

std::uint64_t LogClock::at(double t_s) const {
  const double since_start_ns = static_cast<double>(row_time_ns(t_s)) / (speed > 0 ? speed : 1.0);
  if (!(since_start_ns < 9e18)) return std::numeric_limits<std::uint64_t>::max();  // beyond any run
  return start_unix_ns + static_cast<std::uint64_t>(std::llround(since_start_ns));
}

std::uint64_t unix_now_ns() {
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  return static_cast<std::uint64_t>(now.tv_sec) * 1'000'000'000u + static_cast<std::uint64_t>(now.tv_nsec);
}

}  // namespace hil::bench
