#include "hil/drv/modbus_emulator.hpp"

#include <arpa/inet.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include <spdlog/spdlog.h>

#include "modbus_link.hpp"

namespace hil::drv {
namespace detail {

// A libmodbus server on its own thread: TCP (any number of clients) or RTU. Before each reply
// `refresh` updates the register space from the model; after a write `apply` hands it back.
class ModbusServer {
 public:
  using Hook = std::function<void(modbus_mapping_t*)>;

  ModbusServer(ModbusLinkConfig cfg, const RegisterMap& map, std::string who, Hook refresh, Hook apply)
      : cfg_(std::move(cfg)), who_(std::move(who)), refresh_(std::move(refresh)), apply_(std::move(apply)) {
    const auto [h0, h1] = map.extent(RegisterTable::holding);
    const auto [i0, i1] = map.extent(RegisterTable::input);
    if (tcp()) check_endpoint();
    mapping_ = modbus_mapping_new_start_address(0, 0, 0, 0, h0, h1 - h0, i0, i1 - i0);
    if (mapping_ == nullptr) throw ModbusError(who_ + ": cannot allocate the register space");
    try {
      open();
    } catch (...) {  // the destructor does not run for a constructor that throws
      if (listen_fd_ >= 0) ::close(listen_fd_);
      if (ctx_) modbus_free(ctx_);
      modbus_mapping_free(mapping_);
      throw;
    }
    thread_ = std::thread([this] { run(); });
  }

  ~ModbusServer() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
    close_all();
    if (listen_fd_ >= 0) ::close(listen_fd_);
    if (ctx_) modbus_free(ctx_);
    modbus_mapping_free(mapping_);
  }

  int port() const { return port_; }
  std::uint64_t requests() const { return requests_; }
  std::mutex& model_mutex() { return model_mutex_; }

  std::atomic<bool> silent{false};
  std::atomic<long long> delay_us{0};
  std::atomic<int> exception{0};
  std::atomic<int> write_exception{0};  // the writes only
  std::atomic<bool> drop{false};
  std::atomic<bool> refuse{false};

 private:
  bool tcp() const { return cfg_.transport == ModbusLinkConfig::Transport::tcp; }

  // Before anything is allocated or opened.
  void check_endpoint() {
    // A name or a typo is refused here, before a bind that would not say so: inet_addr() made
    // "localhost" 255.255.255.255, which Linux binds (a broadcast address) and no client reaches.
    in_addr address{};
    if (!cfg_.host.empty() && !ipv4_address(cfg_.host, address)) {
      throw ModbusError(who_ + ": host '" + cfg_.host +
                        "' is not a numeric IPv4 address (e.g. 127.0.0.1, or 0.0.0.0 for every interface; host names "
                        "are not resolved)");
    }
    if (address.s_addr == htonl(INADDR_BROADCAST)) {
      throw ModbusError(who_ + ": 255.255.255.255 is the broadcast address: no client can connect to it");
    }
    listen_address_ = address.s_addr;  // 0.0.0.0 (and no host): every interface
    if (cfg_.port < 0 || cfg_.port > 65535) throw ModbusError(who_ + ": a TCP port is 0..65535 (0: any free port)");
  }

  void open() {
    ctx_ = new_context(cfg_);
    if (ctx_ == nullptr) throw ModbusError(who_ + ": cannot create a libmodbus context: " + modbus_strerror(errno));
    modbus_set_slave(ctx_, cfg_.unit_id);
    modbus_set_indication_timeout(ctx_, 1, 0);  // a half-sent request must not hang the server
    if (tcp()) {
      // One thread serves every client and libmodbus reads a request whole: a client that sent
      // part of one and stalled held all the others for the byte timeout (0.5 s by default) each
      // time. A TCP request is one small write whose bytes arrive together: 20 ms is plenty, and
      // then that client is dropped. (A serial line's characters do come apart: RTU keeps it.)
      modbus_set_byte_timeout(ctx_, 0, 20000);
      // A request libmodbus refuses itself (a function code it does not serve, such as 0x41 or
      // 0x2b, or a read of 0 registers) is answered by modbus_reply only after it has slept the
      // context's response timeout (0.5 s by default) and flushed what else came, so that the rest
      // of a bad frame is not read as a new request: on this one thread, every other client
      // waited 0.5 s per refused request. Over TCP a request is one write, its bytes all in by
      // then: 1 ms (libmodbus refuses 0). RTU keeps libmodbus' 0.5 s: a serial frame trickles in
      // (256 bytes take 0.27 s at 9600 baud), the flush must wait for its tail, and the line's
      // one master waits for that answer anyway.
      modbus_set_response_timeout(ctx_, 0, 1000);
      port_ = cfg_.port;
      if (!listen()) throw ModbusError(who_ + ": cannot listen: " + std::strerror(errno));
    } else if (modbus_connect(ctx_) == -1) {
      throw ModbusError(who_ + ": cannot open the serial line: " + modbus_strerror(errno));
    }
  }

  // Our own listening socket (not modbus_tcp_listen) so that refuse_connections() can close it
  // and listen again on the same port.
  bool listen() {
    // Non-blocking: run() accepts every pending connection in one round, until EAGAIN.
    listen_fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
    if (listen_fd_ < 0) return false;
    const int on = 1;
    ::setsockopt(listen_fd_, SOL_SOCKET, SO_REUSEADDR, &on, sizeof on);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port_));
    a.sin_addr.s_addr = listen_address_;
    socklen_t len = sizeof a;
    if (::bind(listen_fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || ::listen(listen_fd_, SOMAXCONN) != 0 ||
        ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&a), &len) != 0) {
      const int e = errno;
      ::close(listen_fd_);
      listen_fd_ = -1;
      errno = e;
      return false;
    }
    port_ = ntohs(a.sin_port);
    return true;
  }

  void close_all() {
    for (const Client& c : clients_) ::close(c.fd);
    clients_.clear();
  }

  // A TCP client just accepted.
  void add_client(int fd) {
    // A reply that cannot be sent within 20 ms drops that client (handle() fails): a client that
    // sends requests and never reads the replies filled its buffers, and then the server's
    // blocking send held this thread, every other client with it, for as long as that client
    // stayed (and a SIGTERM of `hilbench plant` waited for it). A reply is one small write into
    // the socket's buffer; 20 ms, as for a request's bytes.
    const timeval send_timeout{0, 20000};
    ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &send_timeout, sizeof send_timeout);
    if (clients_.size() >= kMaxClients) {
      // Full: the client idle the longest gives way. Closing the newcomer instead let 64 idle
      // connections (a tool that opens and forgets them) lock every other master out for good.
      const auto idlest = std::min_element(clients_.begin(), clients_.end(),
                                           [](const Client& a, const Client& b) { return a.active < b.active; });
      ::close(idlest->fd);
      clients_.erase(idlest);
      if (!said_full_) {
        said_full_ = true;
        spdlog::warn(
            "{}: {} clients connected on port {}, the most it serves: each newcomer takes the place of the one idle "
            "the longest (said once)",
            who_, kMaxClients, port_);
      }
    }
    clients_.push_back({fd, std::chrono::steady_clock::now()});
  }

  void run() {
    std::vector<std::uint8_t> query(MODBUS_MAX_ADU_LENGTH);
    while (!stop_) {
      if (drop.exchange(false)) {
        if (tcp()) {
          close_all();
        } else {  // RTU has no connection: close and reopen the line
          modbus_close(ctx_);
          std::this_thread::sleep_for(std::chrono::milliseconds(100));
          modbus_connect(ctx_);
        }
      }
      fd_set rd;
      FD_ZERO(&rd);
      int maxfd = -1;
      const auto add = [&](int fd) {
        FD_SET(fd, &rd);
        maxfd = std::max(maxfd, fd);
      };
      if (tcp()) {
        // Refusing: no listening socket at all, so connect() fails with "connection refused".
        if (refuse && listen_fd_ >= 0) ::close(listen_fd_), listen_fd_ = -1;
        if (!refuse && listen_fd_ < 0) listen();
        if (listen_fd_ >= 0) add(listen_fd_);
        for (const Client& c : clients_) add(c.fd);
      } else if (modbus_get_socket(ctx_) >= 0) {
        add(modbus_get_socket(ctx_));
      }
      timeval tv{0, 20000};  // wake up to see stop_, drop and refuse
      if (::select(maxfd + 1, &rd, nullptr, nullptr, &tv) <= 0) continue;
      if (!tcp()) {
        const int rc = modbus_receive(ctx_, query.data());
        if (rc > 0)
          handle(query.data(), rc);
        else if (rc < 0)
          modbus_flush(ctx_);
        continue;
      }
      for (std::size_t i = 0; i < clients_.size();) {
        const int fd = clients_[i].fd;
        if (!FD_ISSET(fd, &rd)) {
          ++i;
          continue;
        }
        modbus_set_socket(ctx_, fd);
        const int rc = modbus_receive(ctx_, query.data());
        // -1: the client left or sent garbage; or its reply could not be sent (it does not read).
        if (rc == -1 || (rc > 0 && !handle(query.data(), rc))) {
          ::close(fd);
          clients_.erase(clients_.begin() + static_cast<std::ptrdiff_t>(i));
          continue;
        }
        clients_[i].active = std::chrono::steady_clock::now();
        ++i;
      }
      // Newcomers after the clients' requests: a client dropped for a newcomer frees its descriptor
      // number, which a later newcomer may get, and rd would say that one is readable.
      if (listen_fd_ >= 0 && FD_ISSET(listen_fd_, &rd)) {
        // Every pending connection in this round: one per round (and a backlog of 8) let a burst
        // of connects overflow the backlog, and each dropped SYN cost its client a 1 s retry.
        // select() cannot watch a descriptor past FD_SETSIZE (glibc aborts the process): such a
        // newcomer is closed at once. A device has few masters: past kMaxClients, add_client()
        // drops the longest idle.
        for (int fd; (fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC)) >= 0;) {
          if (fd >= FD_SETSIZE) {
            ::close(fd);
          } else {
            add_client(fd);
          }
        }
      }
    }
  }

  // False when the reply could not be sent.
  bool handle(const std::uint8_t* q, int len) {
    ++requests_;
    if (silent) return true;
    if (const long long d = delay_us; d > 0) std::this_thread::sleep_for(std::chrono::microseconds(d));
    const std::uint8_t function = q[modbus_get_header_length(ctx_)];
    const bool write = function == 0x06 || function == 0x10 || function == 0x16 || function == 0x17;
    if (const int code = write && write_exception != 0 ? write_exception.load() : exception.load(); code != 0) {
      return modbus_reply_exception(ctx_, q, static_cast<unsigned>(code)) != -1;
    }
    std::lock_guard lock(model_mutex_);
    refresh_(mapping_);
    const int sent = modbus_reply(ctx_, q, len, mapping_);
    if (write) apply_(mapping_);
    return sent != -1;
  }

  ModbusLinkConfig cfg_;
  std::string who_;
  Hook refresh_, apply_;
  modbus_t* ctx_ = nullptr;
  modbus_mapping_t* mapping_ = nullptr;
  int listen_fd_ = -1;
  in_addr_t listen_address_ = htonl(INADDR_ANY);
  int port_ = 0;
  static constexpr std::size_t kMaxClients = 64;
  struct Client {
    int fd;
    std::chrono::steady_clock::time_point active;  // accepted, or its last request
  };
  std::vector<Client> clients_;
  bool said_full_ = false;
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t> requests_{0};
  std::mutex model_mutex_;
  std::thread thread_;
};

}  // namespace detail

namespace {
std::uint16_t* slot(modbus_mapping_t* m, const Register& r) {
  return r.table == RegisterTable::holding ? m->tab_registers + (r.address - m->start_registers)
                                           : m->tab_input_registers + (r.address - m->start_input_registers);
}
void put(modbus_mapping_t* m, const Register* r, double v) {
  if (r) r->encode(v, slot(m, *r));
}
// The map with its names checked: an emulator reads only the names its device knows (a typo is an
// error naming file:line, as for the clients).
RegisterMap allowed(RegisterMap map, const MapNames& names) {
  map.allow_names(names);
  return map;
}
}  // namespace

// ---- drive -------------------------------------------------------------------------------------

struct ModbusDriveEmulator::Impl {
  RegisterMap map;
  DriveModel& model;
  const Register &control, &target, &status, &position;
  const Register *velocity, *fault_code;
  int bit_enable, bit_reset, bit_enabled, bit_fault;
  std::atomic<std::uint16_t> injected_fault{0};
  std::atomic<bool> freeze_position{false};  // the fault API's frozen encoder
  std::atomic<bool> refreeze{false};         // freeze_position(true) since: take the position anew
  std::optional<double> frozen_rad;          // what it reports while frozen (server thread)
  std::atomic<bool> wrap_position{false};    // the fault API's wrapping counter
  std::uint16_t last_control = 0;
  std::unique_ptr<detail::ModbusServer> server;

  Impl(ModbusLinkConfig cfg, RegisterMap m, DriveModel& mdl)
      : map(allowed(std::move(m), ModbusDriveConfig::map_names())),
        model(mdl),
        control(map.at("control")),
        target(map.at("target_position")),
        status(map.at("status")),
        position(map.at("actual_position")),
        velocity(map.find("actual_velocity")),
        fault_code(map.find("fault_code")),
        bit_enable(map.bit("enable", 0)),
        bit_reset(map.bit("fault_reset", 7)),
        bit_enabled(map.bit("enabled", 0)),
        bit_fault(map.bit("fault", 3)) {
    const std::string who = "Modbus drive emulator " + cfg.describe();
    server = std::make_unique<detail::ModbusServer>(
        std::move(cfg), map, who, [this](modbus_mapping_t* mm) { refresh(mm); }, [this](modbus_mapping_t* mm) { apply(mm); });
  }

  bool enabled_bit(modbus_mapping_t* m) const {
    return (static_cast<std::uint16_t>(control.decode(slot(m, control))) >> bit_enable) & 1;
  }

  void refresh(modbus_mapping_t* m) {
    const auto s = model.sample();
    const std::uint16_t code = injected_fault ? injected_fault.load() : (s.fault ? s.fault_code : 0);
    const bool fault = code != 0 || s.fault;
    const bool enabled = enabled_bit(m) && !fault;
    if (!freeze_position || refreeze.exchange(false)) frozen_rad.reset();
    if (freeze_position && !frozen_rad) {
      frozen_rad = s.position_rad;
    }
    const double reported_rad = frozen_rad.value_or(s.position_rad);
    put(m, &position, wrap_position ? position.wrapped(reported_rad) : reported_rad);
    put(m, velocity, frozen_rad ? 0.0 : s.velocity_rad_s);
    put(m, fault_code, code);
    put(m, &status, (enabled ? 1u << bit_enabled : 0u) | (fault ? 1u << bit_fault : 0u));
  }

  void apply(modbus_mapping_t* m) {
    const auto ctl = static_cast<std::uint16_t>(control.decode(slot(m, control)));
    if (((ctl >> bit_reset) & 1) && !((last_control >> bit_reset) & 1)) {  // rising edge
      injected_fault = 0;
      model.reset_fault();
    }
    last_control = ctl;
    const bool fault = injected_fault != 0 || model.sample().fault;
    const bool enabled = ((ctl >> bit_enable) & 1) && !fault;
    const auto s = model.sample();
    model.command(enabled ? target.decode(slot(m, target)) : s.position_rad, enabled);
  }
};

ModbusDriveEmulator::ModbusDriveEmulator(ModbusLinkConfig server, RegisterMap map, DriveModel& model)
    : impl_(std::make_unique<Impl>(std::move(server), std::move(map), model)) {}
ModbusDriveEmulator::~ModbusDriveEmulator() { impl_->server.reset(); }
int ModbusDriveEmulator::port() const { return impl_->server->port(); }
std::uint64_t ModbusDriveEmulator::requests() const { return impl_->server->requests(); }
void ModbusDriveEmulator::raise_fault(std::uint16_t code) {
  std::lock_guard lock(impl_->server->model_mutex());
  impl_->injected_fault = code;
  impl_->model.command(impl_->model.sample().position_rad, false);
}
void ModbusDriveEmulator::set_silent(bool s) { impl_->server->silent = s; }
void ModbusDriveEmulator::freeze_position(bool frozen) {
  // Each freeze holds the position of the first read after it, not one a former freeze took.
  if (frozen) impl_->refreeze = true;
  impl_->freeze_position = frozen;
}
void ModbusDriveEmulator::wrap_position(bool wrap) { impl_->wrap_position = wrap; }
void ModbusDriveEmulator::set_response_delay(std::chrono::microseconds d) { impl_->server->delay_us = d.count(); }
void ModbusDriveEmulator::set_exception(int code) { impl_->server->exception = code; }
void ModbusDriveEmulator::set_write_exception(int code) { impl_->server->write_exception = code; }
void ModbusDriveEmulator::drop_connections() { impl_->server->drop = true; }
void ModbusDriveEmulator::refuse_connections(bool r) { impl_->server->refuse = r; }

// ---- transducer ------------------------------------------------------------------------------

struct ModbusTransducerEmulator::Impl {
  RegisterMap map;
  PressureModel& model;
  const Register& pressure;
  const Register* status;
  int bit_fault;
  std::unique_ptr<detail::ModbusServer> server;

  Impl(ModbusLinkConfig cfg, RegisterMap m, PressureModel& mdl)
      : map(allowed(std::move(m), ModbusTransducerConfig::map_names())),
        model(mdl),
        pressure(map.at("pressure")),
        status(map.find("status")),
        bit_fault(map.bit("fault", 0)) {
    const std::string who = "Modbus transducer emulator " + cfg.describe();
    server = std::make_unique<detail::ModbusServer>(
        std::move(cfg), map, who,
        [this](modbus_mapping_t* mm) {
          put(mm, &pressure, model.pressure_pa());
          put(mm, status, model.sensor_fault() ? 1u << bit_fault : 0u);
        },
        [](modbus_mapping_t*) {});
  }
};

ModbusTransducerEmulator::ModbusTransducerEmulator(ModbusLinkConfig server, RegisterMap map, PressureModel& model)
    : impl_(std::make_unique<Impl>(std::move(server), std::move(map), model)) {}
ModbusTransducerEmulator::~ModbusTransducerEmulator() { impl_->server.reset(); }
int ModbusTransducerEmulator::port() const { return impl_->server->port(); }
std::uint64_t ModbusTransducerEmulator::requests() const { return impl_->server->requests(); }
void ModbusTransducerEmulator::set_silent(bool s) { impl_->server->silent = s; }
void ModbusTransducerEmulator::set_response_delay(std::chrono::microseconds d) { impl_->server->delay_us = d.count(); }
void ModbusTransducerEmulator::set_exception(int code) { impl_->server->exception = code; }
void ModbusTransducerEmulator::set_write_exception(int code) { impl_->server->write_exception = code; }
void ModbusTransducerEmulator::drop_connections() { impl_->server->drop = true; }
void ModbusTransducerEmulator::refuse_connections(bool r) { impl_->server->refuse = r; }

}  // namespace hil::drv
