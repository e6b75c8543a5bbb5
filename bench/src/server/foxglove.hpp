// The Foxglove WebSocket protocol (subprotocol foxglove.websocket.v1) spoken on the telemetry
// endpoint, so Foxglove and Lichtblick can watch a run: JSON channels with JSON Schema, one per
// group of telemetry columns, one with every column (as telemetry.mcap records it), plus the run's
// events. What is pure protocol lives here (the
// channel table, the server's messages, the Message Data frame, the client's requests checked
// as hostile input); the session that carries it is in telemetry_stream.cpp.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "hil/bench/rt/telemetry_channels.hpp"
#include "hil/bench/rt/telemetry_record.hpp"

namespace hil::bench::foxglove {

inline constexpr std::string_view kSubprotocol = "foxglove.websocket.v1";

// The channels of telemetry_channels.hpp (the same as a recorded telemetry.mcap has).
using Channel = TelemetryChannel;

// pressure, angles, observer, loop, events, telemetry: fixed ids, the same for every connection.
const std::vector<Channel>& channels();
const Channel* channel(std::uint32_t id);

nlohmann::json server_info(std::string_view session_id);
nlohmann::json advertise();
nlohmann::json status(int level, std::string_view message);  // 0 info, 1 warning, 2 error

// The JSON payloads of one telemetry record, in the order of channels() (the events channel's is empty).
std::vector<std::string> payloads(const TelemetryRecord& r);

// What one telemetry record (or one event) becomes: the payload for each channel, in the order
// of channels(); empty where the channel has nothing this time.
struct Frame {
  std::uint64_t timestamp_ns = 0;
  std::vector<std::string> payloads;
};
Frame events_frame(std::uint64_t timestamp_ns, std::string event_json);

// Message Data: opcode 0x01, subscription id and timestamp (ns) little-endian, then the payload.
std::string message_data(std::uint32_t subscription_id, std::uint64_t timestamp_ns, std::string_view payload);
// The timestamp of a record at t_s seconds since the run's start: row_time_ns (t_s as telemetry.csv has it).
std::uint64_t timestamp_ns(double t_s);

// A client's text message, checked. Anything not understood is an Error whose text names the
// field at fault; it is answered with a status message, never by closing the connection.
struct Subscribe {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> subscriptions;  // (subscription id, channel id)
};
struct Unsubscribe {
  std::vector<std::uint32_t> subscription_ids;
};
struct Error {
  std::string message;
};
using ClientOp = std::variant<Subscribe, Unsubscribe, Error>;
ClientOp parse_client_op(std::string_view text);

}  // namespace hil::bench::foxglove
