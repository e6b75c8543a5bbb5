#include "hil/drv/socketcan.hpp"

#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/socket.h>

#include <boost/asio/generic/raw_protocol.hpp>
#include <boost/asio/io_context.hpp>
#include <cerrno>
#include <cstring>
#include <system_error>

namespace hil::drv {

namespace asio = boost::asio;
using raw = asio::generic::raw_protocol;

struct SocketCanTransport::Impl {
  asio::io_context& io;
  std::string ifname;
  std::vector<CanFilter> filters;
  raw::socket sock;
  Handler handler;
  bool running = false;

  Impl(asio::io_context& io_, std::string name, std::vector<CanFilter> f)
      : io(io_), ifname(std::move(name)), filters(std::move(f)), sock(io_) {}

  [[noreturn]] void fail(int err, const std::string& what) const {
    throw std::system_error(err, std::generic_category(), "SocketCAN " + ifname + ": " + what);
  }

  void setopt(int level, int opt, const void* value, socklen_t len, const char* what) {
    if (::setsockopt(sock.native_handle(), level, opt, value, len) != 0) fail(errno, what);
  }

  void open() {
    boost::system::error_code ec;
    sock.open(raw(PF_CAN, CAN_RAW), ec);
    if (ec) fail(ec.value(), "socket(PF_CAN, SOCK_RAW, CAN_RAW) failed (does the kernel have CAN?)");
    const unsigned ifindex = ::if_nametoindex(ifname.c_str());
    if (ifindex == 0) fail(errno, "no such network interface");
    if (!filters.empty()) {
      std::vector<can_filter> kf;
      for (const auto& f : filters) {
        // CAN_EFF_FLAG in the mask keeps 29-bit frames out of an 11-bit filter.
        kf.push_back({f.id > CAN_SFF_MASK ? (f.id | CAN_EFF_FLAG) : f.id, f.mask | CAN_EFF_FLAG});
      }
      setopt(SOL_CAN_RAW, CAN_RAW_FILTER, kf.data(), static_cast<socklen_t>(kf.size() * sizeof(can_filter)),
             "setsockopt(CAN_RAW_FILTER)");
    }
    const can_err_mask_t err_mask = CAN_ERR_MASK;
    setopt(SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask, "setsockopt(CAN_RAW_ERR_FILTER)");
    const int on = 1;
    setopt(SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on, "setsockopt(SO_TIMESTAMPNS)");
    sock.non_blocking(true, ec);
    sockaddr_can addr{};
    addr.can_family = AF_CAN;
    addr.can_ifindex = static_cast<int>(ifindex);
    sock.bind(raw::endpoint(&addr, sizeof addr), ec);
    if (ec) fail(ec.value(), "bind failed");
  }

  void arm() {
    sock.async_wait(raw::socket::wait_read, [this](const boost::system::error_code& ec) {
      if (ec || !running) return;
      drain();
      if (running) arm();
    });
  }

  void drain() {
    for (int n = 0; n < 256 && running; ++n) {  // bounded so timers still get their turn
      can_frame cf{};
      alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timespec))];
      iovec iov{&cf, sizeof cf};
      msghdr msg{};
      msg.msg_iov = &iov;
      msg.msg_iovlen = 1;
      msg.msg_control = control;
      msg.msg_controllen = sizeof control;
      const ssize_t r = ::recvmsg(sock.native_handle(), &msg, MSG_DONTWAIT);
      if (r < static_cast<ssize_t>(sizeof cf)) return;  // EAGAIN, or not a classic CAN frame
      CanFrame f;
      f.error = cf.can_id & CAN_ERR_FLAG;
      f.extended = !f.error && (cf.can_id & CAN_EFF_FLAG);
      f.rtr = !f.error && (cf.can_id & CAN_RTR_FLAG);
      f.id = f.error ? (cf.can_id & CAN_ERR_MASK) : f.extended ? (cf.can_id & CAN_EFF_MASK) : (cf.can_id & CAN_SFF_MASK);
      f.dlc = cf.can_dlc > 8 ? 8 : cf.can_dlc;
      std::memcpy(f.data.data(), cf.data, 8);
      f.rx_time = Clock::now();
      for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMPNS) {
          timespec ts;
          std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
          // The kernel stamps with CLOCK_REALTIME; move it onto the steady clock by its age.
          const auto kernel =
              std::chrono::system_clock::time_point(std::chrono::duration_cast<std::chrono::system_clock::duration>(
                  std::chrono::seconds(ts.tv_sec) + std::chrono::nanoseconds(ts.tv_nsec)));
          const auto age = std::chrono::system_clock::now() - kernel;
          if (age >= std::chrono::nanoseconds(0) && age < std::chrono::seconds(1)) f.rx_time -= age;
        }
      }
      handler(f);
    }
  }
};

SocketCanTransport::SocketCanTransport(asio::io_context& io, std::string interface, std::vector<CanFilter> filters)
    : impl_(std::make_unique<Impl>(io, interface, std::move(filters))), name_(std::move(interface)) {
  impl_->open();
}

SocketCanTransport::~SocketCanTransport() {
  stop();
  boost::system::error_code ec;
  impl_->sock.close(ec);
}

void SocketCanTransport::start(Handler on_frame) {
  impl_->handler = std::move(on_frame);
  impl_->running = true;
  impl_->arm();
}

bool SocketCanTransport::send(const CanFrame& f) noexcept {
  can_frame cf{};
  cf.can_id = f.error ? (f.id | CAN_ERR_FLAG) : f.extended ? (f.id | CAN_EFF_FLAG) : f.id;
  if (f.rtr) cf.can_id |= CAN_RTR_FLAG;
  cf.can_dlc = f.dlc > 8 ? 8 : f.dlc;
  std::memcpy(cf.data, f.data.data(), 8);
  return ::send(impl_->sock.native_handle(), &cf, sizeof cf, MSG_DONTWAIT) == static_cast<ssize_t>(sizeof cf);
}

void SocketCanTransport::stop() noexcept {
  impl_->running = false;
  boost::system::error_code ec;
  impl_->sock.cancel(ec);
}

void SocketCanTransport::reopen() {
  const bool was_running = impl_->running;
  stop();
  boost::system::error_code ec;
  impl_->sock.close(ec);
  impl_->open();
  if (was_running) {
    impl_->running = true;
    impl_->arm();
  }
}

CanTransportFactory SocketCanTransport::factory(std::string interface) {
  return [interface](asio::io_context& io, std::vector<CanFilter> filters) -> std::unique_ptr<CanTransport> {
    return std::make_unique<SocketCanTransport>(io, interface, std::move(filters));
  };
}

}  // namespace hil::drv
