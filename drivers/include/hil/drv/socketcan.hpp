// A raw SocketCAN channel (AF_CAN / CAN_RAW) on Boost.Asio: receive filters, error frames
// enabled (CAN_RAW_ERR_FILTER), kernel receive timestamps (SO_TIMESTAMPNS), non-blocking send.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "hil/drv/can.hpp"

namespace hil::drv {

class SocketCanTransport final : public CanTransport {
 public:
  // Opens and binds the socket at once; throws std::system_error naming the interface
  // ("SocketCAN vcan0: ..."), e.g. when the kernel has no CAN or the interface does not exist.
  SocketCanTransport(boost::asio::io_context& io, std::string interface, std::vector<CanFilter> filters);
  ~SocketCanTransport() override;
  SocketCanTransport(const SocketCanTransport&) = delete;
  SocketCanTransport& operator=(const SocketCanTransport&) = delete;

  void start(Handler on_frame) override;
  bool send(const CanFrame& frame) noexcept override;  // real-time safe on the I/O thread
  void stop() noexcept override;
  void reopen() override;
  const std::string& name() const override { return name_; }

  // A factory for clients and emulators: SocketCAN on `interface`.
  static CanTransportFactory factory(std::string interface);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string name_;
};

}  // namespace hil::drv
