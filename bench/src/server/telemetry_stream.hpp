// The telemetry stream: a WebSocket session that accepts the upgrade and then writes what the
// TelemetryHub fans out to it (JSON rows, or Foxglove frames: foxglove.hpp), and the hub itself.
// The HTTP session hands an upgrade request over here (start_telemetry_stream) once the router's
// checks (token, Host, the route's query) have passed.
#pragma once

#include <chrono>
#include <string>

#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/flat_buffer.hpp>

#include "api_reply.hpp"
#include "api_server.hpp"
#include "connection_slot.hpp"

namespace hil::bench::api {

// Whether the client offered the Foxglove subprotocol (Sec-WebSocket-Protocol is a list).
bool offers_foxglove(const Request& req);

// The rows per second a telemetry WebSocket asks for (?rate_hz=N, 20 when not given), once its
// options are checked against its route's (refuse_unknown_query). A half-number (?rate_hz=20abc)
// is refused: silently streaming at another rate than asked for hides the mistake.
double telemetry_rate_hz(const Target& t);

// Starts a telemetry WebSocket on `socket`. read_ahead: the bytes the HTTP session read past the
// upgrade request, the client's first frames. session_id: Foxglove's serverInfo.sessionId, the
// server's. slot: the connection's place; stream_slot: its place in the telemetry share.
void start_telemetry_stream(boost::asio::ip::tcp::socket&& socket, beast::flat_buffer read_ahead, TelemetryHub& hub,
                            bool foxglove, std::string session_id, ConnectionSlot slot, ConnectionSlot stream_slot,
                            std::chrono::milliseconds idle_timeout, Request req, double rate_hz);

}  // namespace hil::bench::api
