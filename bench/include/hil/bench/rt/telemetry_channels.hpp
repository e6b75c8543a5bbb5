// The channels a run's telemetry is published on, written once for the live Foxglove WebSocket
// (server/foxglove.hpp) and the recorded telemetry.mcap (recorder.hpp): topics, JSON Schemas
// built from the one telemetry table (each column's meaning and unit), and the JSON payload of a
// row with the decimals telemetry.csv has, so a live view and a recording carry the same fields,
// and a recording the same numbers as its CSV.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "hil/bench/rt/telemetry_record.hpp"

namespace hil::bench {

struct TelemetryChannel {
  std::uint32_t id;
  std::string topic;
  std::vector<telemetry::Col> columns;  // empty: the events channel
};

// pressure, angles, observer, loop, events, telemetry (every column): fixed ids.
const std::vector<TelemetryChannel>& telemetry_channels();
const TelemetryChannel& events_channel();
// The telemetry channel (telemetry::kTopic) with the columns of `set` (a rig without the truth
// records no truth-only column).
TelemetryChannel telemetry_channel(ColumnSet set);

std::string schema_name(const TelemetryChannel& c);  // "hilbench/pressure"
// JSON Schema: every column a number (null where the rig cannot know it) with its meaning and
// unit; events an object with a "kind" (events.jsonl) or "type" (the server's run notices).
std::string schema_json(const TelemetryChannel& c);
// The JSON object of a row for the channel: the columns' values at the telemetry table's decimals
// (null where not finite). row: telemetry_row's values, indexed by telemetry::index.
std::string payload_json(const TelemetryChannel& c, const TelemetryRow& row);
// A row's time stamp in ns: its t_s as telemetry.csv has it (negative and NaN give 0).
std::uint64_t row_time_ns(double t_s);

// The log times of a run's telemetry.mcap: the wall clock (UTC, ns since 1970) at which a record
// of run time t_s was due, the loop's start plus t_s / speed, so a viewer shows the day and hour
// of the run (the run's own time is the message's t_s).
struct LogClock {
  std::uint64_t start_unix_ns = 0;  // the wall clock at run time 0
  double speed = 1;                 // run seconds per wall-clock second
  std::uint64_t at(double t_s) const;
};
std::uint64_t unix_now_ns();  // the wall clock now (CLOCK_REALTIME)

}  // namespace hil::bench
