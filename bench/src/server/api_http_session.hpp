// The HTTP session of one connection: reads a request (the parser's limits), answers it through
// the router (on the io thread, or on the request worker: api_router.hpp Thread), writes the answer (a
// file streamed from disk, a HEAD's header alone, an answer that waits for a job), and hands a
// WebSocket upgrade to the telemetry stream. The listener (api_listener.cpp) opens and evicts them.
#pragma once

#include <chrono>
#include <memory>
#include <optional>

#include <boost/asio/ip/tcp.hpp>

#include "api_impl.hpp"

namespace hil::bench::api {

class HttpSession;

// A session on an accepted socket, reading its first request.
std::shared_ptr<HttpSession> open_http_session(boost::asio::ip::tcp::socket&& socket, std::shared_ptr<ApiServer::Impl> api);

// Waiting for a request since when (nullopt: serving one, or closed): the connection to give up
// first when the server is at its connection cap.
std::optional<std::chrono::steady_clock::time_point> idle_since(const HttpSession& s);

// Ends the wait for a request (the connection's slot goes to a newcomer). Io thread.
void evict(HttpSession& s);

}  // namespace hil::bench::api
