#include "foxglove.hpp"
#include "request_guard.hpp"

#include <cmath>
#include <limits>

namespace hil::bench::foxglove {
namespace {

using nlohmann::json;
// Integers in a client's message: JSON numbers that are whole and fit 32 bits unsigned.
bool as_u32(const json& j, std::uint32_t& out) {
  if (j.is_number_unsigned() && j.get<std::uint64_t>() <= std::numeric_limits<std::uint32_t>::max()) {
    out = static_cast<std::uint32_t>(j.get<std::uint64_t>());
    return true;
  }
  return false;
}

}  // namespace

const std::vector<Channel>& channels() { return telemetry_channels(); }

const Channel* channel(std::uint32_t id) {
  for (const auto& c : channels())
    if (c.id == id) return &c;
  return nullptr;
}

json server_info(std::string_view session_id) {
  return {{"op", "serverInfo"},
          {"name", "hilbench"},
          {"capabilities", json::array()},
          {"metadata", {{"time", "message timestamps are the run's time since its start"}}},
          {"sessionId", std::string(session_id)}};
}

json advertise() {
  json list = json::array();
  for (const auto& c : channels()) {
    list.push_back({{"id", c.id},
                    {"topic", c.topic},
                    {"encoding", "json"},
                    {"schemaName", schema_name(c)},
                    {"schema", schema_json(c)},
                    {"schemaEncoding", "jsonschema"}});
  }
  return {{"op", "advertise"}, {"channels", list}};
}

json status(int level, std::string_view message) {
  return {{"op", "status"}, {"level", level}, {"message", std::string(message)}};
}

std::vector<std::string> payloads(const TelemetryRecord& r) {
  const TelemetryRow row = telemetry_row(r);
  std::vector<std::string> out;
  out.reserve(channels().size());
  for (const auto& c : channels()) {
    if (c.columns.empty()) {
      out.emplace_back();
      continue;
    }
    out.push_back(payload_json(c, row));
  }
  return out;
}

Frame events_frame(std::uint64_t timestamp_ns, std::string event_json) {
  Frame f{timestamp_ns, std::vector<std::string>(channels().size())};
  for (std::size_t i = 0; i < channels().size(); ++i)
    if (channels()[i].id == events_channel().id) f.payloads[i] = std::move(event_json);
  return f;
}

std::string message_data(std::uint32_t subscription_id, std::uint64_t timestamp_ns, std::string_view payload) {
  std::string out;
  out.reserve(13 + payload.size());
  out.push_back(static_cast<char>(0x01));
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>((subscription_id >> (8 * i)) & 0xff));
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<char>((timestamp_ns >> (8 * i)) & 0xff));
  out.append(payload);
  return out;
}

std::uint64_t timestamp_ns(double t_s) { return row_time_ns(t_s); }

ClientOp parse_client_op(std::string_view text) {
  // Bounded before it is parsed (a message is at most 64 KiB: 65 536 levels of brackets otherwise).
  if (too_deep(text, kMaxRequestJsonDepth))
    return Error{"the message nests objects and arrays deeper than " + std::to_string(kMaxRequestJsonDepth) + " levels"};
  const json j = json::parse(text, nullptr, false);
  if (j.is_discarded()) return Error{"not a JSON text message"};
  if (!j.is_object() || !j.contains("op") || !j["op"].is_string()) return Error{"'op' must be a string"};
  const std::string op = j["op"].get<std::string>();
  if (op == "subscribe") {
    if (!j.contains("subscriptions") || !j["subscriptions"].is_array())
      return Error{"subscribe: 'subscriptions' must be an array"};
    Subscribe s;
    for (std::size_t i = 0; i < j["subscriptions"].size(); ++i) {
      const json& e = j["subscriptions"][i];
      std::uint32_t id = 0, channel_id = 0;
      const std::string where = "subscribe: subscriptions[" + std::to_string(i) + "]";
      if (!e.is_object() || !e.contains("id") || !as_u32(e["id"], id))
        return Error{where + ".id must be an integer in [0, 2^32)"};
      if (!e.contains("channelId") || !as_u32(e["channelId"], channel_id))
        return Error{where + ".channelId must be an integer in [0, 2^32)"};
      s.subscriptions.emplace_back(id, channel_id);
    }
    return s;
  }
  if (op == "unsubscribe") {
    if (!j.contains("subscriptionIds") || !j["subscriptionIds"].is_array())
      return Error{"unsubscribe: 'subscriptionIds' must be an array"};
    Unsubscribe u;
    for (std::size_t i = 0; i < j["subscriptionIds"].size(); ++i) {
      std::uint32_t id = 0;
      if (!as_u32(j["subscriptionIds"][i], id))
        return Error{"unsubscribe: subscriptionIds[" + std::to_string(i) + "] must be an integer in [0, 2^32)"};
      u.subscription_ids.push_back(id);
    }
    return u;
  }
  return Error{"op '" + op.substr(0, 64) + "' is not supported by this server (it advertises channels only)"};
}

}  // namespace hil::bench::foxglove
