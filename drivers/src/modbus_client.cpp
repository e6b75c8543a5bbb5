#include <arpa/inet.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <functional>
#include <mutex>
#include <thread>

#include "hil/config.hpp"
#include "hil/drv/modbus.hpp"
#include "modbus_link.hpp"
#include "setup_util.hpp"

namespace hil::drv {

using std::chrono::milliseconds;

// ---- configuration ---------------------------------------------------------------------------

namespace {
// "<who>: status register 3 reports a fault (bit 3, status 0x0008<more>)": a device's fault bit,
// said with where it was read (the drive adds its fault_code).
std::string fault_bit_text(const std::string& who, const RegisterMap& map, int bit, std::uint16_t status,
                           const std::string& more = "") {
  char hex[8];
  std::snprintf(hex, sizeof hex, "%04X", status);
  return who + ": status register " + std::to_string(map.at("status").address) + " reports a fault (bit " + std::to_string(bit) +
         ", status 0x" + hex + more + ")";
}
}  // namespace

namespace {
// libmodbus cannot be interrupted inside a transaction: a run's end, an abort's included, waits for
// the one in flight up to this long (it was 600 s). A device that needs longer to answer is no
// device for a control loop.
constexpr long long kMaxResponseTimeoutMs = 10000;

// The serial rates libmodbus 3.1 sets on Linux (modbus-rtu.c): it makes any other rate 9600 baud
// without a word ("Unknown baud rate ... (B9600 used)" only in its debug mode).
constexpr std::array<int, 23> kBaudRates{110,     300,     600,     1200,    2400,    4800,    9600,   19200,
                                         38400,   57600,   115200,  230400,  460800,  500000,  576000, 921600,
                                         1000000, 1152000, 1500000, 2500000, 3000000, 3500000, 4000000};

RegisterMap map_from(const cfg::Node& n, const MapNames& names) {
  const auto m = n.at("register_map");
  RegisterMap map = m.is_scalar() ? RegisterMap::load(m.resolve_path(m.text())) : RegisterMap::from_yaml(m);
  map.allow_names(names);
  return map;
}

// Checks that `name` is in the map (and writable when asked), naming the map file otherwise.
void need(const RegisterMap& map, const char* name, bool writable, const char* why) {
  const Register* r = map.find(name);
  if (r == nullptr) throw ModbusError(map.origin() + ": register map needs '" + name + "' (" + why + ")");
  if (writable && r->table != RegisterTable::holding) {
    throw ModbusError(map.origin() + ": '" + name + "' must be a holding register: the client writes it");
  }
}
}  // namespace

ModbusLinkConfig ModbusLinkConfig::from_yaml(const cfg::Node& n) {
  n.allow_keys({"transport", "host", "port", "device", "baud", "parity", "data_bits", "stop_bits", "unit_id",
                "response_timeout_ms", "poll_period_ms", "reconnect"});
  ModbusLinkConfig c;
  const std::string t = n.text("transport", "tcp");
  if (t == "rtu")
    c.transport = Transport::rtu;
  else if (t != "tcp")
    n.at("transport").fail("must be tcp or rtu, got '" + t + "'");
  // The other transport's keys would be ignored: a `baud:` on a TCP link is a mistake to say.
  const bool tcp = c.transport == Transport::tcp;
  const std::vector<std::string> other_keys = tcp ? std::vector<std::string>{"device", "baud", "parity", "data_bits", "stop_bits"}
                                                  : std::vector<std::string>{"host", "port"};
  for (const auto& key : other_keys) {
    if (n.has(key)) n.at(key).fail(std::string("a ") + (tcp ? "tcp" : "rtu") + " link has no " + key);
  }
  if (c.transport == Transport::tcp) {
    c.host = n.text("host", c.host);
    in_addr address{};
    if (auto h = n.find("host")) {
      h->require(detail::ipv4_address(c.host, address) && address.s_addr != htonl(INADDR_ANY) &&
                     address.s_addr != htonl(INADDR_BROADCAST),
                 "must be the device's numeric IPv4 address (libmodbus resolves no names: 'localhost' became "
                 "255.255.255.255)");
    }
    const long long port = n.at("port").integer();
    n.at("port").require(port >= 1 && port <= 65535, "a device's TCP port is 1..65535");
    c.port = static_cast<int>(port);
  } else {
    c.device = n.text("device");
    std::string rates;
    for (const int r : kBaudRates) rates += (rates.empty() ? "" : ", ") + std::to_string(r);
    if (auto b = n.find("baud")) {
      const long long baud = b->integer();
      b->require(std::find(kBaudRates.begin(), kBaudRates.end(), baud) != kBaudRates.end(),
                 "must be one of " + rates + " (libmodbus makes any other 9600)");
      c.baud = static_cast<int>(baud);
    }
    const std::string p = n.text("parity", "N");
    if (p != "N" && p != "E" && p != "O") n.at("parity").fail("must be N, E or O, got '" + p + "'");
    c.parity = p[0];
    c.data_bits = static_cast<int>(n.integer_in("data_bits", 8, 5, 8, "libmodbus makes any other 8"));
    c.stop_bits = static_cast<int>(n.integer_in("stop_bits", 1, 1, 2, "libmodbus makes any other 2"));
  }
  // A client asks one device: unit 0 is a broadcast, which no device answers (and 248..255 are
  // reserved).
  c.unit_id =
      static_cast<int>(n.integer_in("unit_id", 1, 1, 247, "a device's unit id; 0 is a broadcast, which no device answers"));
  c.response_timeout = n.milliseconds_in("response_timeout_ms", c.response_timeout, 1, kMaxResponseTimeoutMs,
                                         "an abort waits for the transaction in flight, which libmodbus cannot cut short");
  c.poll_period = n.milliseconds_in("poll_period_ms", c.poll_period, 1, detail::kMaxWaitMs);
  if (auto r = n.find("reconnect")) {
    r->allow_keys({"initial_ms", "max_ms"});
    c.reconnect_initial = r->milliseconds_in("initial_ms", c.reconnect_initial, 1, detail::kMaxWaitMs);
    c.reconnect_max = r->milliseconds_in("max_ms", c.reconnect_max, 1, detail::kMaxWaitMs);
    if (c.reconnect_max < c.reconnect_initial) r->at("max_ms").fail("must be >= initial_ms");
  }
  return c;
}

std::string ModbusLinkConfig::describe() const {
  if (transport == Transport::tcp) return "tcp " + host + ":" + std::to_string(port) + " unit " + std::to_string(unit_id);
  return "rtu " + device + " " + std::to_string(baud) + " " + std::to_string(data_bits) + parity + std::to_string(stop_bits) +
         " unit " + std::to_string(unit_id);
}

ModbusDriveConfig ModbusDriveConfig::from_yaml(const cfg::Node& n) {
  n.allow_keys({"link", "register_map", "transition_ms"});
  ModbusDriveConfig c{ModbusLinkConfig::from_yaml(n.at("link")), map_from(n, map_names())};
  c.transition_timeout = n.milliseconds_in("transition_ms", c.transition_timeout, 1, detail::kMaxWaitMs);
  return c;
}

const MapNames& ModbusDriveConfig::map_names() {
  static const MapNames names{{"control", "target_position", "status", "actual_position", "actual_velocity", "fault_code"},
                              {"enable", "fault_reset", "enabled", "fault"}};
  return names;
}

ModbusDriveConfig ModbusDriveConfig::load(const std::filesystem::path& file) {
  const auto root = cfg::Node::load_file(file);
  if (auto d = root.find("modbus_drive")) return from_yaml(*d);
  return from_yaml(root);
}

ModbusTransducerConfig ModbusTransducerConfig::from_yaml(const cfg::Node& n) {
  n.allow_keys({"link", "register_map"});
  return {ModbusLinkConfig::from_yaml(n.at("link")), map_from(n, map_names())};
}

const MapNames& ModbusTransducerConfig::map_names() {
  static const MapNames names{{"pressure", "status"}, {"fault"}};
  return names;
}

ModbusTransducerConfig ModbusTransducerConfig::load(const std::filesystem::path& file) {
  const auto root = cfg::Node::load_file(file);
  if (auto d = root.find("modbus_transducer")) return from_yaml(*d);
  return from_yaml(root);
}

// ---- the libmodbus link ----------------------------------------------------------------------

namespace detail {

Failure classify(int err) {
  if (err > MODBUS_ENOBASE && err <= EMBXGTAR) return Failure::exception;
  if (err == ETIMEDOUT) return Failure::timeout;
  if (err > EMBXGTAR && err <= EMBBADSLAVE) return Failure::protocol;
  return Failure::connection;
}

std::string error_text(int err, const ModbusLinkConfig& cfg) {
  if (classify(err) == Failure::exception) {
    const int code = err - MODBUS_ENOBASE;
    return std::string(modbus_exception_name(code)) + " (exception " + std::to_string(code) + ")";
  }
  if (err == ETIMEDOUT) return "no reply within " + std::to_string(cfg.response_timeout.count()) + " ms (timeout)";
  return modbus_strerror(err);
}

bool ipv4_address(const std::string& host, in_addr& out) { return ::inet_pton(AF_INET, host.c_str(), &out) == 1; }

modbus_t* new_context(const ModbusLinkConfig& c) {
  if (c.transport == ModbusLinkConfig::Transport::tcp) return modbus_new_tcp(c.host.c_str(), c.port);
  return modbus_new_rtu(c.device.c_str(), c.baud, c.parity, c.data_bits, c.stop_bits);
}

void ModbusLink::connect() {
  close();
  ctx_ = new_context(cfg_);
  if (ctx_ == nullptr) throw ModbusError(std::string("cannot create a libmodbus context: ") + modbus_strerror(errno));
  modbus_set_slave(ctx_, cfg_.unit_id);
  const auto us = std::chrono::duration_cast<std::chrono::microseconds>(cfg_.response_timeout).count();
  modbus_set_response_timeout(ctx_, static_cast<uint32_t>(us / 1000000), static_cast<uint32_t>(us % 1000000));
  // Between two bytes of one reply, at most 100 ms (a character at 1200 baud is 9 ms): equal to
  // the response timeout, a device trickling a byte every few seconds stretched one read to about
  // 20 response timeouts, minutes in which a run's end and an abort waited.
  const auto byte_us = std::min<long long>(us, 100000);
  modbus_set_byte_timeout(ctx_, static_cast<uint32_t>(byte_us / 1000000), static_cast<uint32_t>(byte_us % 1000000));
  if (modbus_connect(ctx_) == -1) {
    const int e = errno;
    close();
    throw ModbusError(std::string("cannot connect: ") + modbus_strerror(e));
  }
}

void ModbusLink::close() {
  if (ctx_ == nullptr) return;
  modbus_close(ctx_);
  modbus_free(ctx_);
  ctx_ = nullptr;
}

bool ModbusLink::read(const RegisterBlock& b, std::uint16_t* dest) {
  const int rc = b.table == RegisterTable::holding ? modbus_read_registers(ctx_, b.start, b.count, dest)
                                                   : modbus_read_input_registers(ctx_, b.start, b.count, dest);
  if (rc == b.count) return true;
  err_ = rc == -1 ? errno : EMBBADDATA;
  return false;
}

bool ModbusLink::write(const Register& r, const std::uint16_t* words) {
  const int rc = r.words() == 1 ? modbus_write_register(ctx_, r.address, words[0])
                                : modbus_write_registers(ctx_, r.address, r.words(), words);
  if (rc != -1) return true;
  err_ = errno;
  return false;
}

}  // namespace detail

// ---- the polling engine both clients share ---------------------------------------------------

namespace {

struct Slot {  // where a register's words land in the read buffer
  const Register* reg = nullptr;
  std::size_t offset = 0;
  double read(const std::uint16_t* buf) const { return reg->decode(buf + offset); }
};

class Poller {
 public:
  Poller(const ModbusLinkConfig& cfg, std::string who, const RegisterMap& map, const std::vector<std::string>& reads)
      : cfg_(cfg), who_(std::move(who)), link_(cfg_), blocks_(map.blocks(reads)) {
    std::size_t off = 0;
    for (const auto& b : blocks_) {
      block_offset_.push_back(off);
      off += b.count;
    }
    buf_.resize(off);
    for (const auto& name : reads) {
      Slot s;
      s.reg = map.find(name);
      if (s.reg == nullptr) {
        slots_.push_back(s);
        continue;
      }
      for (std::size_t i = 0; i < blocks_.size(); ++i) {
        const auto& b = blocks_[i];
        if (b.table == s.reg->table && s.reg->address >= b.start && s.reg->address + s.reg->words() <= b.start + b.count) {
          s.offset = block_offset_[i] + (s.reg->address - b.start);
        }
      }
      slots_.push_back(s);
    }
    health_.heartbeat_timeout = cfg_.response_timeout;
  }
  ~Poller() { stop(); }

  const std::string& who() const { return who_; }
  const Slot& slot(std::size_t i) const { return slots_[i]; }
  const std::uint16_t* buffer() const { return buf_.data(); }
  DeviceHealth& health() { return health_; }  // I/O thread (or configure, before it starts)
  Mailbox<DeviceHealth>& health_box() { return health_box_; }
  bool fresh_connection() const { return fresh_; }

  // Reads every block; false with `doing` set on failure.
  bool read_all() {
    for (std::size_t i = 0; i < blocks_.size(); ++i) {
      const auto& b = blocks_[i];
      ++health_.tx_frames;
      if (!link_.read(b, buf_.data() + block_offset_[i])) {
        doing_ = "reading " + std::string(to_string(b.table)) + " registers " + std::to_string(b.start) + ".." +
                 std::to_string(b.start + b.count - 1) + " (" + b.names + ")";
        return false;
      }
      ++health_.rx_frames;
    }
    health_.last_heartbeat = Clock::now();
    health_.connected = true;
    health_.failing = false;
    return true;
  }

  bool write(const Register& r, const std::uint16_t* words) {
    ++health_.tx_frames;
    if (!link_.write(r, words)) {
      doing_ = "writing " + r.where();
      return false;
    }
    ++health_.rx_frames;
    return true;
  }

  std::string failure_text() const { return who_ + ": " + doing_ + ": " + detail::error_text(link_.error(), cfg_); }

  // Setup: connect and run one cycle, throwing what went wrong.
  void first_cycle(const std::function<bool()>& cycle) {
    try {
      link_.connect();
    } catch (const ModbusError& e) {
      throw ModbusError(who_ + ": " + e.what());
    }
    fresh_ = true;
    if (!cycle()) {
      const std::string text = failure_text();
      link_.close();
      throw ModbusError(text);
    }
    fresh_ = false;
    health_box_.store(health_);
  }

  void start(std::function<bool()> cycle, std::function<void()> publish) {
    cycle_ = std::move(cycle);
    publish_ = std::move(publish);
    thread_ = std::thread([this] { run(); });
  }

  void stop() {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    cv_.notify_all();
    if (thread_.joinable()) thread_.join();
    link_.close();
  }

 private:
  bool sleep_until(Clock::time_point t) {
    std::unique_lock lock(mutex_);
    return !cv_.wait_until(lock, t, [this] { return stop_; });
  }
  bool stopping() {
    std::lock_guard lock(mutex_);
    return stop_;
  }

  void run() {
    auto backoff = cfg_.reconnect_initial;
    auto next = Clock::now();
    while (!stopping()) {
      if (!link_.is_open()) {
        try {
          link_.connect();
          ++health_.reconnects;
          fresh_ = true;
          backoff = cfg_.reconnect_initial;
        } catch (const ModbusError& e) {
          health_.connected = false;
          health_.failing = true;
          ++health_.tx_failed;
          health_.set_last_error(std::string(who_) + ": " + e.what());
          publish_();
          if (!sleep_until(Clock::now() + backoff)) return;
          backoff = std::min(backoff * 2, cfg_.reconnect_max);
          continue;
        }
      }
      if (cycle_()) {
        fresh_ = false;
      } else {
        const auto f = detail::classify(link_.error());
        health_.set_last_error(failure_text());
        health_.failing = true;
        ++health_.tx_failed;
        if (f == detail::Failure::exception) {
          ++health_.aborts_or_exceptions;  // the device answered: the link is fine
        } else {
          if (f == detail::Failure::timeout) ++health_.timeouts;
          if (f == detail::Failure::protocol) ++health_.malformed;
          // A fresh connection leaves no stale reply behind (TCP) and resets the line (RTU).
          link_.close();
          health_.connected = false;
          publish_();
          if (f == detail::Failure::connection && !sleep_until(Clock::now() + cfg_.reconnect_initial)) return;
          continue;
        }
      }
      publish_();
      next += cfg_.poll_period;
      const auto now = Clock::now();
      if (next < now) next = now;
      if (!sleep_until(next)) return;
    }
  }

  ModbusLinkConfig cfg_;
  std::string who_;
  detail::ModbusLink link_;
  std::vector<RegisterBlock> blocks_;
  std::vector<std::size_t> block_offset_;
  std::vector<std::uint16_t> buf_;
  std::vector<Slot> slots_;
  std::string doing_;
  bool fresh_ = true;
  DeviceHealth health_;
  Mailbox<DeviceHealth> health_box_;
  std::function<bool()> cycle_;
  std::function<void()> publish_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool stop_ = false;
  std::thread thread_;
};

using detail::wait_for;

}  // namespace

// ---- the drive -------------------------------------------------------------------------------

struct ModbusDrive::Impl {
  enum { kStatus, kPosition, kVelocity, kFaultCode };
  ModbusDriveConfig cfg;
  Poller poller;
  const Register& control;
  const Register& target;
  int bit_enable, bit_reset, bit_enabled, bit_fault;
  Mailbox<DriveCommand> command;
  Mailbox<DriveFeedback> feedback;
  std::atomic<bool> enable_requested{false};
  std::atomic<bool> reset_requested{false};
  // Set by cancel_setup(), for good: activate() stops waiting for the enabled bit (up to
  // transition_timeout_ms, 600 s at most) and configure() refuses to start.
  std::atomic<bool> setup_cancelled{false};
  // The loop's liveness (cfg.loop_hang_bound): write() stores when it ran; 0 while no loop runs it.
  std::atomic<Clock::rep> loop_write_count{0};
  SwitchOff off;  // setup thread
  // I/O thread
  DriveFeedback fb;
  bool loop_hung = false;  // latched for this client's life: enable stays off
  bool prev_cmd_reset = false;
  bool reset_pulse = false;
  std::uint16_t last_control = 0xFFFF;
  std::uint16_t last_target[2] = {0xFFFF, 0xFFFF};
  // The newest write failed (an exception reply: the device refuses its target or control word):
  // a fault until a write goes through, since the drive then no longer does what the loop asks.
  bool write_failed = false;
  // actual_position moved by more than half its register's count range between two polls: a wrap
  // of the count (or a corrupt reply), never a move. Latched for this client's life (a rig makes
  // a new one at each setup), with the last trusted position kept and held as the target.
  bool position_jump = false;
  double position_jump_limit_rad = 0;  // half the register's count span

  static const ModbusDriveConfig& checked(const ModbusDriveConfig& c) {
    need(c.map, "control", true, "the enable and fault-reset bits");
    need(c.map, "target_position", true, "in radians after scale/offset");
    need(c.map, "status", false, "the enabled and fault bits");
    need(c.map, "actual_position", false, "in radians after scale/offset");
    return c;
  }

  explicit Impl(ModbusDriveConfig c)
      : cfg(std::move(checked(c))),
        poller(cfg.link, "Modbus drive " + cfg.link.describe(), cfg.map,
               {"status", "actual_position", "actual_velocity", "fault_code"}),
        control(cfg.map.at("control")),
        target(cfg.map.at("target_position")),
        bit_enable(cfg.map.bit("enable", 0)),
        bit_reset(cfg.map.bit("fault_reset", 7)),
        bit_enabled(cfg.map.bit("enabled", 0)),
        bit_fault(cfg.map.bit("fault", 3)),
        position_jump_limit_rad(0.5 * cfg.map.at("actual_position").count_span()) {}

  // The newest actual_position, unless it jumped (see position_jump).
  void take_position(double pos_rad) {
    if (position_jump) return;
    if (fb.valid && std::abs(pos_rad - fb.position_rad) > position_jump_limit_rad) {
      position_jump = true;
      char text[200];
      std::snprintf(text, sizeof text,
                    ": position jump: actual_position from %.5g to %.5g rad in one poll, over half its register's range "
                    "(%.5g rad): a wrapped count; set it up again",
                    fb.position_rad, pos_rad, position_jump_limit_rad);
      poller.health().set_last_error(poller.who() + text);
      return;
    }
    fb.position_rad = pos_rad;
  }

  bool cycle() {
    if (!poller.read_all()) return false;
    const auto* buf = poller.buffer();
    const auto status = static_cast<std::uint16_t>(poller.slot(kStatus).read(buf));
    fb.statusword = status;
    fb.enabled = (status >> bit_enabled) & 1;
    fb.fault = (status >> bit_fault) & 1;
    take_position(poller.slot(kPosition).read(buf));
    fb.velocity_rad_s = poller.slot(kVelocity).reg ? poller.slot(kVelocity).read(buf) : kNaN;
    fb.valid = true;
    fb.rx_time = Clock::now();
    ++fb.sequence;
    auto& h = poller.health();
    const bool fault_was = h.statusword >> bit_fault & 1;
    h.statusword = status;
    h.fault = fb.fault;
    if (fb.fault && poller.slot(kFaultCode).reg) h.last_emcy_code = static_cast<std::uint16_t>(poller.slot(kFaultCode).read(buf));
    if (fb.fault && !fault_was) {
      char code[48] = "";
      if (poller.slot(kFaultCode).reg) std::snprintf(code, sizeof code, ", fault_code 0x%04X", h.last_emcy_code);
      h.set_last_error(fault_bit_text(poller.who(), cfg.map, bit_fault, status, code));
    }

    const DriveCommand cmd = command.load();
    if (cmd.fault_reset && !prev_cmd_reset) reset_requested = true;
    prev_cmd_reset = cmd.fault_reset;
    check_loop();
    const bool enable = enable_requested && cmd.enable && !loop_hung;
    if (reset_pulse) {
      reset_pulse = false;  // one poll with the bit set, then low again: one rising edge
    } else if (reset_requested.exchange(false)) {
      reset_pulse = true;
    }
    const bool follow = enable && fb.enabled && !fb.fault && !position_jump;
    std::uint16_t words[2] = {0, 0};
    target.encode(follow ? cmd.target_position_rad : fb.position_rad, words);
    // A fresh connection, or a write refused last time (retried each poll until one goes through).
    const bool fresh = poller.fresh_connection() || write_failed;
    if (fresh || words[0] != last_target[0] || (target.words() == 2 && words[1] != last_target[1])) {
      if (!poller.write(target, words)) return write_failed = true, false;
      last_target[0] = words[0], last_target[1] = words[1];
      write_failed = false;
    }
    std::uint16_t ctl[2] = {static_cast<std::uint16_t>((enable ? 1u << bit_enable : 0u) | (reset_pulse ? 1u << bit_reset : 0u)),
                            0};
    if (fresh || ctl[0] != last_control) {
      if (!poller.write(control, ctl)) return write_failed = true, false;
      last_control = ctl[0];
      write_failed = false;
    }
    return true;
  }

  // Past the bound without a write() from the loop: the control register's safe write (enable
  // off) goes out in this cycle, and the drive is a fault from here on.
  void check_loop() {
    const Clock::rep count = loop_write_count.load(std::memory_order_acquire);
    if (loop_hung || cfg.loop_hang_bound.count() <= 0 || count == 0) return;
    const auto silent = Clock::now() - Clock::time_point(Clock::duration(count));
    if (silent <= cfg.loop_hang_bound) return;
    loop_hung = true;
    poller.health().set_last_error(poller.who() + ": control loop hung: no period completed for " +
                                   std::to_string(std::chrono::duration_cast<std::chrono::milliseconds>(silent).count()) +
                                   " ms (the bench allows " + std::to_string(cfg.loop_hang_bound.count()) +
                                   " ms); the bench wrote enable off itself");
  }

  void publish() {
    auto& h = poller.health();
    fb.fault = (fb.statusword >> bit_fault) & 1 || !h.connected || write_failed || position_jump || loop_hung;
    h.fault = fb.fault;
    feedback.store(fb);
    poller.health_box().store(h);
  }
};

ModbusDrive::ModbusDrive(ModbusDriveConfig config) : impl_(std::make_unique<Impl>(std::move(config))) {}
ModbusDrive::~ModbusDrive() { impl_->poller.stop(); }

void ModbusDrive::configure() {
  auto& m = *impl_;
  if (m.setup_cancelled) throw ModbusError(m.poller.who() + ": configure() cancelled");
  m.poller.first_cycle([&m] { return m.cycle(); });
  m.command.store({m.fb.position_rad, false, false});
  m.publish();
  m.poller.start([&m] { return m.cycle(); }, [&m] { m.publish(); });
}

void ModbusDrive::activate() {
  auto& m = *impl_;
  const auto fb = m.feedback.load();
  if (!fb.valid) throw ModbusError(m.poller.who() + ": activate() before configure()");
  m.command.store({fb.position_rad, true, false});
  m.loop_write_count.store(0, std::memory_order_release);  // watched from the loop's first write()
  if (fb.fault) m.reset_requested = true;
  m.enable_requested = true;
  const bool enabled = wait_for(m.cfg.transition_timeout, [&] { return m.setup_cancelled || m.feedback.load().enabled; });
  if (m.setup_cancelled) {
    m.enable_requested = false;  // nothing will run the drive: do not leave it to enable later
    throw ModbusError(m.poller.who() + ": activate() cancelled");
  }
  if (!enabled) {
    throw ModbusError(m.poller.who() + ": status register " + std::to_string(m.cfg.map.at("status").address) +
                      " did not report enabled within " + std::to_string(m.cfg.transition_timeout.count()) +
                      " ms (last error: " + std::string(health().last_error_text()) + ")");
  }
}

void ModbusDrive::cancel_setup() noexcept { impl_->setup_cancelled = true; }

void ModbusDrive::deactivate() {
  auto& m = *impl_;
  m.loop_write_count.store(0, std::memory_order_release);  // no loop runs the drive from here
  m.enable_requested = false;
  const auto asked = Clock::now();
  // Off as a poll after the request shows it (an older reading may predate the write).
  const bool off = wait_for(m.cfg.transition_timeout, [&] {
    const auto fb = m.feedback.load();
    return fb.valid && !fb.enabled && fb.rx_time > asked;
  });
  const auto fb = m.feedback.load();
  m.off = {.path = "register",
           .asked_by = "deactivate()",
           .after_ms = std::chrono::duration<double, std::milli>(Clock::now() - asked).count(),
           .state = fb.rx_time > asked ? (fb.enabled ? "enabled" : "disabled") : "unknown (no poll answered)",
           .off = off};
  if (!off) {
    throw ModbusError(m.poller.who() + ": did not disable within " + std::to_string(m.cfg.transition_timeout.count()) + " ms");
  }
}

DriveFeedback ModbusDrive::read(Clock::time_point, Clock::duration) noexcept { return impl_->feedback.load(); }
void ModbusDrive::write(Clock::time_point, Clock::duration, const DriveCommand& command) noexcept {
  impl_->command.store(command);
  impl_->loop_write_count.store(Clock::now().time_since_epoch().count(), std::memory_order_release);
}
SwitchOff ModbusDrive::last_switch_off() const { return impl_->off; }
DeviceHealth ModbusDrive::health() const noexcept { return detail::with_age(impl_->poller.health_box()); }

// ---- the transducer --------------------------------------------------------------------------

struct ModbusTransducer::Impl {
  ModbusTransducerConfig cfg;
  Poller poller;
  int bit_fault;
  Mailbox<PressureReading> reading;
  PressureReading r;

  static const ModbusTransducerConfig& checked(const ModbusTransducerConfig& c) {
    need(c.map, "pressure", false, "in Pa after scale/offset");
    return c;
  }
  explicit Impl(ModbusTransducerConfig c)
      : cfg(std::move(checked(c))),
        poller(cfg.link, "Modbus transducer " + cfg.link.describe(), cfg.map, {"pressure", "status"}),
        bit_fault(cfg.map.bit("fault", 0)) {}

  bool cycle() {
    if (!poller.read_all()) return false;
    const auto* buf = poller.buffer();
    r.pressure_pa = poller.slot(0).read(buf);
    const auto status = poller.slot(1).reg ? static_cast<std::uint16_t>(poller.slot(1).read(buf)) : 0;
    const bool fault_was = r.fault;
    r.fault = (status >> bit_fault) & 1;
    r.valid = true;
    r.rx_time = Clock::now();
    ++r.sequence;
    poller.health().statusword = status;
    if (r.fault && !fault_was) poller.health().set_last_error(fault_bit_text(poller.who(), cfg.map, bit_fault, status));
    if (!std::isfinite(r.pressure_pa))
      poller.health().set_last_error(poller.who() + ": the pressure register reads " + std::to_string(r.pressure_pa));
    return true;
  }
  void publish() {
    auto& h = poller.health();
    h.fault = r.fault || !h.connected;
    PressureReading out = r;
    out.fault = h.fault;
    reading.store(out);
    poller.health_box().store(h);
  }
};

ModbusTransducer::ModbusTransducer(ModbusTransducerConfig config) : impl_(std::make_unique<Impl>(std::move(config))) {}
ModbusTransducer::~ModbusTransducer() { impl_->poller.stop(); }

void ModbusTransducer::configure() {
  auto& m = *impl_;
  m.poller.first_cycle([&m] { return m.cycle(); });
  m.publish();
  m.poller.start([&m] { return m.cycle(); }, [&m] { m.publish(); });
}

PressureReading ModbusTransducer::read(Clock::time_point, Clock::duration) noexcept { return impl_->reading.load(); }
DeviceHealth ModbusTransducer::health() const noexcept { return detail::with_age(impl_->poller.health_box()); }

}  // namespace hil::drv
