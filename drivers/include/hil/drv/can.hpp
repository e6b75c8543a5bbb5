// CAN frames, the transport interface the CANopen code talks to, and error-frame decoding.
// Implementations: SocketCanTransport (socketcan.hpp) and LoopbackTransport (can_loopback.hpp).
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "hil/drv/io_types.hpp"

namespace boost::asio {
class io_context;
}

namespace hil::drv {

struct CanFrame {
  std::uint32_t id = 0;  // 11- or 29-bit identifier; for an error frame the CAN_ERR_* class bits
  std::uint8_t dlc = 0;
  bool extended = false;
  bool rtr = false;
  bool error = false;  // an error frame (Linux CAN_ERR_FLAG): data[] holds the details
  std::array<std::uint8_t, 8> data{};
  Clock::time_point rx_time{};  // receive time (kernel timestamp mapped onto the steady clock)
};

// A receive filter as in SocketCAN: a frame passes when (frame.id & mask) == (id & mask).
struct CanFilter {
  std::uint32_t id = 0;
  std::uint32_t mask = 0;
};

// Where frames go. The CANopen logic only sees this. All calls happen on the thread that runs
// the io_context the transport was made with; handlers are called there too.
class CanTransport {
 public:
  using Handler = std::function<void(const CanFrame&)>;
  virtual ~CanTransport() = default;
  // Starts receiving: data frames that pass the filters, and error frames. Throws on failure.
  virtual void start(Handler on_frame) = 0;
  // Queues a frame without blocking; false when the interface refused it (e.g. queue full,
  // bus-off). Real-time safe on the I/O thread: one non-blocking system call, no allocation.
  virtual bool send(const CanFrame& frame) noexcept = 0;
  // Stops receiving; no handler is called afterwards.
  virtual void stop() noexcept = 0;
  // Closes and reopens the channel (used by the bus-off "recover" policy). Throws on failure.
  virtual void reopen() = 0;
  virtual const std::string& name() const = 0;
};

using CanTransportFactory = std::function<std::unique_ptr<CanTransport>(boost::asio::io_context&, std::vector<CanFilter>)>;

// What an error frame says (linux/can/error.h), decoded.
struct CanErrorInfo {
  bool bus_off = false;
  bool restarted = false;       // controller restarted after bus-off
  bool error_passive = false;   // rx or tx error counter above 127
  bool error_warning = false;   // rx or tx error counter above 96
  bool back_to_active = false;  // controller reports error-active again
  bool controller_problem = false;
  bool tx_timeout = false, lost_arbitration = false, protocol_violation = false;
  bool transceiver = false, no_ack = false, bus_error = false;
  std::uint8_t tx_errors = 0, rx_errors = 0;  // data[6], data[7] when the driver fills them
  std::string text;                           // e.g. "bus-off", "controller problem: rx error-passive"
};

CanErrorInfo decode_error_frame(const CanFrame& frame);

// The bus state an error-frame sequence implies. Error-active until told otherwise.
class BusStateTracker {
 public:
  // Returns true when the state changed.
  bool update(const CanErrorInfo& info);
  BusState state() const { return state_; }
  void reset() { state_ = BusState::error_active; }

 private:
  BusState state_ = BusState::error_active;
};

// Builds an error frame of the kind a CAN controller driver would report (for emulators and tests).
enum class EmulatedBusError { bus_off, restarted, error_passive, error_warning, back_to_active };
CanFrame make_error_frame(EmulatedBusError kind);

// Frame text as candump prints it, e.g. "605#2F60600008000000" (for logs and test messages).
std::string to_string(const CanFrame& frame);

}  // namespace hil::drv
