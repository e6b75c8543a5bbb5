// The Foxglove WebSocket protocol's pure parts against its specification
// (github.com/foxglove/ws-protocol docs/spec.md): the Message Data frame's bytes, the advertised
// channels and their JSON Schemas, and the client's requests taken as hostile input.
#include "server/foxglove.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <string>

namespace {

using namespace hil::bench;
using nlohmann::json;

TEST(Foxglove, MessageDataIsOpcodeThenLittleEndianIdAndTimestampThenPayload) {
  const std::string frame = foxglove::message_data(0x01020304u, 0x1122334455667788ull, "{\"a\":1}");
  const std::string expected = std::string("\x01", 1) + std::string("\x04\x03\x02\x01", 4) +
                               std::string("\x88\x77\x66\x55\x44\x33\x22\x11", 8) + "{\"a\":1}";
  EXPECT_EQ(frame, expected);
}

TEST(Foxglove, TimestampsAreTheRunsTimeInNanoseconds) {
  EXPECT_EQ(foxglove::timestamp_ns(0.0), 0u);
  EXPECT_EQ(foxglove::timestamp_ns(1.5), 1'500'000'000u);
  EXPECT_EQ(foxglove::timestamp_ns(12.001), 12'001'000'000u);
  EXPECT_EQ(foxglove::timestamp_ns(-1.0), 0u);
  EXPECT_EQ(foxglove::timestamp_ns(std::nan("")), 0u);
}

TEST(Foxglove, EveryChannelIsJsonWithASchemaNamingItsFields) {
  const json a = foxglove::advertise();
  ASSERT_EQ(a["op"], "advertise");
  ASSERT_EQ(a["channels"].size(), foxglove::channels().size());
  std::set<std::uint32_t> ids;
  TelemetryRecord r;
  r.step.t_s = 2.5;
  r.step.p_meas_pa = 1.2e6;
  const auto payloads = foxglove::payloads(r);
  for (std::size_t i = 0; i < foxglove::channels().size(); ++i) {
    const json& c = a["channels"][i];
    EXPECT_TRUE(ids.insert(c["id"].get<std::uint32_t>()).second) << "channel ids are unique";
    EXPECT_EQ(c["encoding"], "json");
    EXPECT_EQ(c["schemaEncoding"], "jsonschema");
    const json schema = json::parse(c["schema"].get<std::string>());
    EXPECT_EQ(schema["type"], "object");
    const auto& columns = foxglove::channels()[i].columns;
    if (columns.empty()) {
      EXPECT_TRUE(payloads[i].empty()) << "events carry no telemetry";
      continue;
    }
    const json payload = json::parse(payloads[i]);
    ASSERT_EQ(payload.size(), schema["properties"].size()) << c["topic"];
    for (const auto& [field, spec] : schema["properties"].items()) {
      ASSERT_TRUE(payload.contains(field)) << c["topic"] << " lacks " << field;
      EXPECT_FALSE(spec["description"].get<std::string>().empty());
    }
    EXPECT_EQ(payload["t_s"], 2.5);
  }
  const json p = json::parse(payloads[0]);
  EXPECT_EQ(foxglove::channels()[0].topic, "/hilbench/pressure");
  EXPECT_DOUBLE_EQ(p["p_meas_mpa"].get<double>(), 1.2);
}

TEST(Foxglove, SubscribeAndUnsubscribeAreRead) {
  const auto s =
      foxglove::parse_client_op(R"({"op":"subscribe","subscriptions":[{"id":0,"channelId":1},{"id":7,"channelId":5}]})");
  ASSERT_TRUE(std::holds_alternative<foxglove::Subscribe>(s));
  const auto& subs = std::get<foxglove::Subscribe>(s).subscriptions;
  ASSERT_EQ(subs.size(), 2u);
  EXPECT_EQ(subs[1], (std::pair<std::uint32_t, std::uint32_t>{7, 5}));
  const auto u = foxglove::parse_client_op(R"({"op":"unsubscribe","subscriptionIds":[7]})");
  ASSERT_TRUE(std::holds_alternative<foxglove::Unsubscribe>(u));
  EXPECT_EQ(std::get<foxglove::Unsubscribe>(u).subscription_ids, std::vector<std::uint32_t>{7});
}

TEST(Foxglove, BadRequestsAreErrorsNamingTheField) {
  auto error = [](std::string_view text) {
    const auto op = foxglove::parse_client_op(text);
    return std::holds_alternative<foxglove::Error>(op) ? std::get<foxglove::Error>(op).message : std::string("(accepted)");
  };
  EXPECT_NE(error("{\"op\":").find("not a JSON"), std::string::npos);
  EXPECT_NE(error("[1,2]").find("'op'"), std::string::npos);
  EXPECT_NE(error(R"({"op":5})").find("'op'"), std::string::npos);
  EXPECT_NE(error(R"({"op":"subscribe"})").find("'subscriptions'"), std::string::npos);
  EXPECT_NE(error(R"({"op":"subscribe","subscriptions":[{"id":-1,"channelId":1}]})").find("subscriptions[0].id"),
            std::string::npos);
  EXPECT_NE(error(R"({"op":"subscribe","subscriptions":[{"id":1,"channelId":1.5}]})").find("subscriptions[0].channelId"),
            std::string::npos);
  EXPECT_NE(error(R"({"op":"subscribe","subscriptions":[{"id":1,"channelId":1},{"id":4294967296,"channelId":1}]})")
                .find("subscriptions[1].id"),
            std::string::npos);
  EXPECT_NE(error(R"({"op":"unsubscribe","subscriptionIds":["a"]})").find("subscriptionIds[0]"), std::string::npos);
  EXPECT_NE(error(R"({"op":"setParameters","parameters":[]})").find("'setParameters' is not supported"), std::string::npos);
}

}  // namespace
