#include "hil/drv/can_loopback.hpp"

#include <algorithm>
#include <atomic>
#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>

namespace hil::drv {

struct LoopbackBus::Endpoint {
  Endpoint(boost::asio::io_context& i, std::vector<CanFilter> f) : io(i), filters(std::move(f)) {}
  boost::asio::io_context& io;
  std::vector<CanFilter> filters;
  CanTransport::Handler handler;
  std::atomic<bool> active{false};

  bool passes(const CanFrame& f) const {
    if (f.error) return true;  // every endpoint asks for error frames, as SocketCanTransport does
    if (filters.empty()) return true;
    return std::any_of(filters.begin(), filters.end(), [&](const CanFilter& c) { return (f.id & c.mask) == (c.id & c.mask); });
  }
};

void LoopbackBus::inject(const CanFrame& frame) { deliver(frame, nullptr); }

void LoopbackBus::set_tap(std::function<void(const CanFrame&)> tap) {
  std::lock_guard lock(mutex_);
  tap_ = std::move(tap);
}

CanTransportFactory LoopbackBus::factory(std::string name) {
  return [this, name](boost::asio::io_context& io, std::vector<CanFilter> filters) -> std::unique_ptr<CanTransport> {
    return std::make_unique<LoopbackTransport>(io, *this, name, std::move(filters));
  };
}

void LoopbackBus::attach(const std::shared_ptr<Endpoint>& ep) {
  std::lock_guard lock(mutex_);
  endpoints_.push_back(ep);
}

void LoopbackBus::detach(const Endpoint* ep) {
  std::lock_guard lock(mutex_);
  std::erase_if(endpoints_, [ep](const auto& e) { return e.get() == ep; });
}

void LoopbackBus::deliver(const CanFrame& frame, const Endpoint* from) {
  std::lock_guard lock(mutex_);
  if (tap_) tap_(frame);
  for (const auto& ep : endpoints_) {
    if (ep.get() == from || !ep->active || !ep->passes(frame)) continue;
    CanFrame copy = frame;
    boost::asio::post(ep->io, [ep, copy]() mutable {
      if (!ep->active) return;
      copy.rx_time = Clock::now();
      ep->handler(copy);
    });
  }
}

LoopbackTransport::LoopbackTransport(boost::asio::io_context& io, LoopbackBus& bus, std::string name,
                                     std::vector<CanFilter> filters)
    : bus_(bus), name_(std::move(name)), ep_(std::make_shared<LoopbackBus::Endpoint>(io, std::move(filters))) {
  bus_.attach(ep_);
}

LoopbackTransport::~LoopbackTransport() {
  stop();
  bus_.detach(ep_.get());
}

void LoopbackTransport::start(Handler on_frame) {
  ep_->handler = std::move(on_frame);
  ep_->active = true;
}

bool LoopbackTransport::send(const CanFrame& frame) noexcept {
  try {
    bus_.deliver(frame, ep_.get());
    return true;
  } catch (...) {
    return false;
  }
}

void LoopbackTransport::stop() noexcept { ep_->active = false; }

}  // namespace hil::drv
