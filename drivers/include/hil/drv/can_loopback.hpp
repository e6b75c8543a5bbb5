// An in-process CAN bus for unit tests: every frame one endpoint sends reaches every other
// endpoint whose filters pass it (like vcan with local loopback, without the own-message echo).
// A test double: the vcan tests run the same code on a real kernel bus. Not real-time safe
// (send() locks the bus and allocates a posted handler).
#pragma once

#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "hil/drv/can.hpp"

namespace hil::drv {

class LoopbackBus {
 public:
  LoopbackBus() = default;
  LoopbackBus(const LoopbackBus&) = delete;
  LoopbackBus& operator=(const LoopbackBus&) = delete;

  // Puts a frame on the bus from outside (like cansend). Thread-safe.
  void inject(const CanFrame& frame);
  // Sees every frame on the bus, sent or injected (like candump). Called on the sender's thread.
  void set_tap(std::function<void(const CanFrame&)> tap);
  // A factory making endpoints on this bus. The bus must outlive them.
  CanTransportFactory factory(std::string name = "loopback");

  struct Endpoint;

 private:
  friend class LoopbackTransport;
  void attach(const std::shared_ptr<Endpoint>& ep);
  void detach(const Endpoint* ep);
  void deliver(const CanFrame& frame, const Endpoint* from);

  std::mutex mutex_;
  std::vector<std::shared_ptr<Endpoint>> endpoints_;
  std::function<void(const CanFrame&)> tap_;
};

class LoopbackTransport final : public CanTransport {
 public:
  LoopbackTransport(boost::asio::io_context& io, LoopbackBus& bus, std::string name, std::vector<CanFilter> filters);
  ~LoopbackTransport() override;
  LoopbackTransport(const LoopbackTransport&) = delete;
  LoopbackTransport& operator=(const LoopbackTransport&) = delete;

  void start(Handler on_frame) override;
  bool send(const CanFrame& frame) noexcept override;
  void stop() noexcept override;
  void reopen() override {}
  const std::string& name() const override { return name_; }

 private:
  LoopbackBus& bus_;
  std::string name_;
  std::shared_ptr<LoopbackBus::Endpoint> ep_;
};

}  // namespace hil::drv
