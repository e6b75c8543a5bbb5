// Private helpers shared by the clients' setup paths (blocking; never on a real-time thread).
#pragma once

#include <chrono>
#include <thread>

#include "hil/drv/io_types.hpp"

namespace hil::drv::detail {

// The longest any configured wait may be, in ms: a setup call blocks for (a few of) these, and a
// huge one would overflow the clock arithmetic (the SDO budget multiplies sdo_ms by the tries)
// instead of waiting.
inline constexpr long long kMaxWaitMs = 600000;

// Polls `pred` every 2 ms until it holds (true) or `timeout` passes (false).
template <class Pred>
bool wait_for(std::chrono::milliseconds timeout, Pred pred) {
  const auto until = Clock::now() + timeout;
  while (!pred()) {
    if (Clock::now() > until) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return true;
}

// The health a mailbox holds, with heartbeat_age filled in for now. Real-time safe.
inline DeviceHealth with_age(const Mailbox<DeviceHealth>& box) noexcept {
  DeviceHealth h = box.load();
  if (h.last_heartbeat != Clock::time_point{}) h.heartbeat_age = Clock::now() - h.last_heartbeat;
  return h;
}

}  // namespace hil::drv::detail
