// A place among the server's open connections, held while a connection lives (the listener's cap,
// api_listener.cpp; the telemetry streams' share, telemetry_stream.cpp).
#pragma once

#include <atomic>
#include <memory>

namespace hil::bench::api {

// One open client connection, HTTP or WebSocket, counted while it lives: the server takes at
// most kMaxConnections at once. A flood of idle sockets (20 000 from one client) took every file
// descriptor the process had, and the next run could not write its run.json.
// Telemetry streams take at most kMaxStreams of them: 256 streams took every connection, and an
// abort was closed at accept for as long as they stayed. The other kMaxConnections - kMaxStreams
// are the operator's requests' (HTTP), where the longest idle one gives way to a newcomer, so a
// control request always finds a place. A stream past its share is refused 503.
constexpr int kMaxConnections = 320;
constexpr int kMaxStreams = 256;
class ConnectionSlot {
 public:
  explicit ConnectionSlot(std::shared_ptr<std::atomic<int>> open) : open_(std::move(open)) { ++*open_; }
  ConnectionSlot(ConnectionSlot&& other) noexcept = default;  // the moved-from slot holds nothing
  ConnectionSlot(const ConnectionSlot&) = delete;
  ConnectionSlot& operator=(const ConnectionSlot&) = delete;
  ConnectionSlot& operator=(ConnectionSlot&&) = delete;
  ~ConnectionSlot() {
    if (open_) --*open_;
  }

 private:
  std::shared_ptr<std::atomic<int>> open_;
};

}  // namespace hil::bench::api
