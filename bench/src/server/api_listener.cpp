// The listener: accepts connections up to the server's cap (connection_slot.hpp), evicting the
// longest-idle HTTP connection for a newcomer at the cap, and hands each to an HTTP session.
#include <chrono>
#include <cstdio>
#include <random>

#include <boost/asio/strand.hpp>
#include <spdlog/spdlog.h>

#include "api_http_session.hpp"
#include "api_impl.hpp"
#include "connection_slot.hpp"

namespace hil::bench {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
using tcp = asio::ip::tcp;
using namespace api;

// This server process's Foxglove sessionId: the same for every connection to it and new at each
// start, so that a client reconnecting can tell a restarted server from a dropped connection. The
// start time and random bits, never an address (a heap pointer told any client the process's
// memory layout, which address-space randomisation is there to hide).
std::string new_session_id() {
  std::random_device random;
  const auto start_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  char text[64];
  std::snprintf(text, sizeof text, "%llx-%08x%08x", static_cast<unsigned long long>(start_ns), random(), random());
  return text;
}

}  // namespace

ApiServer::Impl::Impl(asio::io_context& io_, ApiOptions o, CampaignRunner& r, TelemetryHub& h)
    : io(io_),
      options(std::move(o)),
      runner(r),
      hub(h),
      acceptor(io_),
      jobs(options.max_waiting_jobs),
      session_id(new_session_id()) {}

void ApiServer::Impl::accept() {
  acceptor.async_accept(asio::make_strand(io), [self = shared_from_this()](beast::error_code ec, tcp::socket socket) {
    if (ec == asio::error::operation_aborted) return;
    if (ec) return self->accept();
    if (*self->open_connections >= kMaxConnections && !self->evict_longest_idle()) {
      // Every connection is busy (WebSocket streams, requests being served): this one is closed
      // at once, no read, no reply to build; said in the log at most once a minute.
      beast::error_code ignored;
      socket.close(ignored);
      const auto now = std::chrono::steady_clock::now();
      if (now - self->last_refusal_logged > std::chrono::minutes(1)) {
        spdlog::warn("{} connections are open and none is idle: refusing more until some close", kMaxConnections);
        self->last_refusal_logged = now;
      }
      return self->accept();
    }
    if (self->http_sessions.size() >= 2 * kMaxConnections)
      std::erase_if(self->http_sessions, [](const auto& w) { return w.expired(); });
    self->http_sessions.push_back(open_http_session(std::move(socket), self));
    self->accept();
  });
}

// At the connection cap, the connection that has waited longest for a request gives its place to
// the newcomer: a flood of idle sockets (256 of them) otherwise locked the operator out until they
// closed or the 60 s idle timeout ended them, in the middle of a run that may need an abort.
// False when no connection waits (all stream telemetry or are being served).
bool ApiServer::Impl::evict_longest_idle() {
  std::erase_if(http_sessions, [](const auto& w) { return w.expired(); });
  std::shared_ptr<HttpSession> oldest;
  for (const auto& w : http_sessions) {
    const auto s = w.lock();
    if (s && idle_since(*s) && (!oldest || *idle_since(*s) < *idle_since(*oldest))) oldest = s;
  }
  if (!oldest) return false;
  evict(*oldest);
  const auto now = std::chrono::steady_clock::now();
  if (now - last_refusal_logged > std::chrono::minutes(1)) {
    spdlog::warn("{} connections are open: closing the longest idle one for each new one", kMaxConnections);
    last_refusal_logged = now;
  }
  return true;
}

}  // namespace hil::bench
