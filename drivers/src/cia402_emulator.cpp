#include "hil/drv/cia402_emulator.hpp"

#include <algorithm>
#include <atomic>
#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <future>
#include <cmath>
#include <map>
#include <optional>
#include <thread>

#include "hil/config.hpp"
#include "hil/drv/socketcan.hpp"

namespace hil::drv {

namespace asio = boost::asio;
using namespace canopen;
using cia402::State;

Cia402EmulatorConfig Cia402EmulatorConfig::from_yaml(const cfg::Node& n) {
  n.allow_keys({"interface", "node_id", "units", "pdos", "interpolation_period", "mode_display_delay_ms", "following_error",
                "quick_stop_ramp", "heartbeat_consumer", "abort_connection_option", "node_guarding", "own_pdo_ids"});
  Cia402EmulatorConfig c;
  if (auto i = n.find("interface")) check_can_interface_name(*i);
  c.interface = n.text("interface", c.interface);
  const long long node = n.at("node_id").integer();
  n.at("node_id").require(node >= 1 && node <= 127, "a CANopen node id is 1..127");
  c.node_id = static_cast<std::uint8_t>(node);
  if (auto u = n.find("units")) c.units = DriveUnits::from_yaml(*u);
  c.pdos = static_cast<int>(n.integer_in("pdos", c.pdos, 1, 4));
  c.interpolation_period = n.boolean("interpolation_period", c.interpolation_period);
  c.mode_display_delay = n.milliseconds_in("mode_display_delay_ms", c.mode_display_delay, 0, 10000);
  c.following_error = n.boolean("following_error", c.following_error);
  c.quick_stop_ramp = n.boolean("quick_stop_ramp", c.quick_stop_ramp);
  c.heartbeat_consumer = n.boolean("heartbeat_consumer", c.heartbeat_consumer);
  c.abort_connection_option = n.boolean("abort_connection_option", c.abort_connection_option);
  c.node_guarding = n.boolean("node_guarding", c.node_guarding);
  c.own_pdo_ids = n.boolean("own_pdo_ids", c.own_pdo_ids);
  return c;
}

Cia402EmulatorConfig Cia402EmulatorConfig::load(const std::filesystem::path& file) {
  const auto root = cfg::Node::load_file(file);
  if (auto d = root.find("cia402_emulator")) return from_yaml(*d);
  return from_yaml(root);
}

namespace {
constexpr std::uint32_t key(std::uint16_t index, std::uint8_t sub) { return (std::uint32_t{index} << 8) | sub; }

constexpr std::uint32_t kAbortNoObject = 0x06020000, kAbortNoSub = 0x06090011, kAbortReadOnly = 0x06010002,
                        kAbortLength = 0x06070010, kAbortCommand = 0x05040001, kAbortState = 0x08000022,
                        kAbortNotMappable = 0x06040041, kAbortPdoLength = 0x06040042, kAbortValue = 0x06090030,
                        kAbortIncompatible = 0x06040043;
constexpr int kConsumerEntries = 4;  // 0x1016:01..04

std::uint16_t statusword_for(State s) {
  switch (s) {
    case State::not_ready_to_switch_on: return 0x0000;
    case State::switch_on_disabled: return 0x0040;
    case State::ready_to_switch_on: return 0x0031;  // + voltage enabled (bit 4)
    case State::switched_on: return 0x0033;
    case State::operation_enabled: return 0x0037;
    case State::quick_stop_active: return 0x0017;
    case State::fault_reaction_active: return 0x001F;
    case State::fault: return 0x0008;
  }
  return 0;
}
}  // namespace

struct Cia402DriveEmulator::Impl {
  struct Obj {
    std::uint32_t value = 0;
    std::uint8_t size = 4;
    bool writable = false;
    bool mappable = false;
  };

  Cia402EmulatorConfig cfg;
  DriveModel& model;
  std::uint8_t n;
  asio::io_context io;
  asio::executor_work_guard<asio::io_context::executor_type> work{io.get_executor()};
  std::unique_ptr<CanTransport> tr;
  asio::steady_timer hb_timer{io}, flood_timer{io}, consumer_timer{io}, own_clock{io};
  std::thread thread;

  std::atomic<std::uint8_t> nmt_now{static_cast<std::uint8_t>(NmtState::boot_up)};
  std::atomic<std::uint8_t> state_now{static_cast<std::uint8_t>(State::not_ready_to_switch_on)};
  std::atomic<std::uint64_t> syncs{0};
  std::atomic<bool> hb_stopped{false}, silent{false};
  std::atomic<bool> freeze_position{false};   // the fault API's frozen encoder
  std::atomic<bool> refreeze{false};          // freeze_position(true) since: take the position anew
  std::optional<std::int32_t> frozen_counts;  // what it reports while frozen (I/O thread)
  std::atomic<long long> delay_us{0};

  // I/O thread only.
  std::map<std::uint32_t, Obj> od;
  std::map<std::uint32_t, std::uint32_t> sdo_failures;
  std::array<std::array<std::uint8_t, 8>, 4> rpdo_data{};
  std::array<bool, 4> rpdo_pending{};
  std::array<int, 4> tpdo_count{};
  State state = State::not_ready_to_switch_on;
  std::uint16_t last_cw = 0;
  std::uint32_t flood_id = 1;
  int flood_per_ms = 0;
  Clock::time_point mode_written{};     // when 0x6060 last changed
  Clock::time_point following_since{};  // outside the following error window since
  bool following_out = false;
  Clock::time_point qs_t0{};  // quick stop ramp: start, position, speed
  double qs_p0 = 0, qs_v0 = 0;
  bool qs_started = false;
  // Heartbeat consumer (0x1016), per entry: monitoring started (a heartbeat came since the entry
  // was written or the last event) and when the last one came.
  std::array<bool, kConsumerEntries> consumer_started{};
  std::array<Clock::time_point, kConsumerEntries> consumer_last{};
  std::atomic<std::uint64_t> consumer_events{0};
  std::optional<Cia402DriveEmulator::ConsumerEvent> last_event;
  // Node guarding: the toggle bit of the next reply; life guarding started (a request came since
  // the reset or the last event) and when the last request came.
  bool guard_toggle = false;
  bool guarded = false;
  Clock::time_point last_guard{};

  Impl(Cia402EmulatorConfig c, DriveModel& m) : cfg(std::move(c)), model(m), n(cfg.node_id) {}

  void def(std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size, bool writable, bool mappable = false) {
    od[key(index, sub)] = {value, size, writable, mappable};
  }
  std::uint32_t get(std::uint16_t index, std::uint8_t sub) { return od.at(key(index, sub)).value; }
  void set(std::uint16_t index, std::uint8_t sub, std::uint32_t v) { od.at(key(index, sub)).value = v; }

  void reset_communication() {
    def(0x1000, 0, 0x00020192, 4, false);  // CiA 402, servo drive
    def(0x1001, 0, 0, 1, false);
    def(0x1006, 0, 0, 4, true);  // communication cycle period, us
    for (int k = 0; k <= kConsumerEntries; ++k) od.erase(key(0x1016, static_cast<std::uint8_t>(k)));
    od.erase(key(0x1017, 0)), od.erase(key(0x100C, 0)), od.erase(key(0x100D, 0));
    if (cfg.node_guarding) {
      def(0x100C, 0, 0, 2, true);  // guard time, ms
      def(0x100D, 0, 0, 1, true);  // life time factor
    } else {
      def(0x1017, 0, 0, 2, true);
    }
    guard_toggle = false;
    guarded = false;
    if (cfg.heartbeat_consumer && !cfg.node_guarding) {
      def(0x1016, 0, kConsumerEntries, 1, false);
      for (int k = 1; k <= kConsumerEntries; ++k) def(0x1016, static_cast<std::uint8_t>(k), 0, 4, true);
    }
    consumer_started = {};
    def(0x1018, 0, 4, 1, false);
    def(0x1018, 1, 0x00000ABC, 4, false);  // vendor (made up)
    def(0x1018, 2, 0x00000402, 4, false);
    def(0x1018, 3, 1, 4, false);
    def(0x1018, 4, 1, 4, false);
    for (int i = 0; i < 4; ++i) {  // a drive with fewer PDOs does not have the others at all
      for (std::uint16_t base : {0x1400, 0x1600, 0x1800, 0x1A00}) {
        for (std::uint8_t s = 0; s <= 8; ++s) od.erase(key(static_cast<std::uint16_t>(base + i), s));
      }
    }
    for (std::uint16_t k = 0; k < static_cast<std::uint16_t>(cfg.pdos); ++k) {
      def(0x1400 + k, 0, 2, 1, false);
      const bool own = cfg.own_pdo_ids && k > 0;
      def(0x1400 + k, 1, own ? 0x500u + 0x20u * k + n : kRpdo1 + 0x100u * k + n, 4, true);
      def(0x1400 + k, 2, 0xFF, 1, true);
      def(0x1800 + k, 0, 2, 1, false);
      def(0x1800 + k, 1, own ? 0x40000000u | (0x480u + 0x20u * k + n) : kTpdo1 + 0x100u * k + n, 4, true);
      def(0x1800 + k, 2, 0xFF, 1, true);
      def(0x1600 + k, 0, k == 0 ? 1 : 0, 1, true);
      def(0x1A00 + k, 0, k == 0 ? 1 : 0, 1, true);
      for (std::uint8_t s = 1; s <= 8; ++s) {
        def(0x1600 + k, s, k == 0 && s == 1 ? 0x60400010 : 0, 4, true);
        def(0x1A00 + k, s, k == 0 && s == 1 ? 0x60410010 : 0, 4, true);
      }
    }
    rpdo_pending = {};
    tpdo_count = {};
  }

  void reset_application() {
    def(cia402::kErrorCode, 0, 0, 2, false, true);
    def(cia402::kControlword, 0, 0, 2, true, true);
    def(cia402::kStatusword, 0, 0, 2, false, true);
    def(cia402::kModesOfOperation, 0, 0, 1, true, true);
    def(cia402::kModesDisplay, 0, 0, 1, false, true);
    def(cia402::kPositionActual, 0, 0, 4, false, true);
    def(cia402::kVelocityActual, 0, 0, 4, false, true);
    def(cia402::kTargetPosition, 0, 0, 4, true, true);
    def(cia402::kSupportedDriveModes, 0, 0x00000081, 4, false);  // profile position, cyclic synchronous position
    if (cfg.interpolation_period) {
      def(cia402::kInterpolationPeriod, 0, 2, 1, false);
      def(cia402::kInterpolationPeriod, 1, 1, 1, true);
      def(cia402::kInterpolationPeriod, 2, static_cast<std::uint8_t>(-3), 1, true);
    }
    if (cfg.following_error) {
      def(cia402::kFollowingErrorWindow, 0, 0xFFFFFFFF, 4, true);
      def(cia402::kFollowingErrorTimeout, 0, 10, 2, true);
    }
    def(cia402::kQuickStopOption, 0, cfg.quick_stop_ramp ? 2 : 0, 2, false);
    if (cfg.abort_connection_option) def(cia402::kAbortConnectionOption, 0, 1, 2, true);
    if (cfg.quick_stop_ramp) def(cia402::kQuickStopDeceleration, 0, 0x7FFFFFFF, 4, true);
    mode_written = {};
    following_out = false;
    state = State::not_ready_to_switch_on;
    last_cw = 0;
    app_step();
  }

  void boot(bool application) {
    if (application) reset_application();
    reset_communication();
    set_nmt(NmtState::boot_up);
    if (!silent) send(heartbeat(n, NmtState::boot_up));
    set_nmt(NmtState::pre_operational);
    arm_heartbeat();
  }

  void set_nmt(NmtState s) { nmt_now = static_cast<std::uint8_t>(s); }
  NmtState nmt() const { return static_cast<NmtState>(nmt_now.load()); }

  void send(const CanFrame& f) { tr->send(f); }

  void send_late(const CanFrame& f) {
    const long long d = delay_us;
    if (d <= 0) return send(f);
    auto t = std::make_shared<asio::steady_timer>(io, std::chrono::microseconds(d));
    t->async_wait([this, t, f](const boost::system::error_code& ec) {
      if (!ec && !silent) send(f);
    });
  }

  void arm_heartbeat() {
    hb_timer.cancel();
    if (!od.contains(key(0x1017, 0))) return;  // node guarding only
    const auto period = std::chrono::milliseconds(get(0x1017, 0));
    if (period.count() == 0) return;
    hb_timer.expires_after(period);
    hb_timer.async_wait([this](const boost::system::error_code& ec) {
      if (ec) return;
      if (!hb_stopped && !silent) send(heartbeat(n, nmt()));
      arm_heartbeat();
    });
  }

  // -- heartbeat consumer (0x1016) --
  void on_heartbeat(const CanFrame& f) {
    if (f.rtr && f.id == kHeartbeat + n) return on_guard_request();
    if (!cfg.heartbeat_consumer || cfg.node_guarding || f.rtr || f.dlc < 1) return;
    const std::uint32_t node = f.id - kHeartbeat;
    const auto now = Clock::now();
    for (int k = 0; k < kConsumerEntries; ++k) {
      const std::uint32_t e = get(0x1016, static_cast<std::uint8_t>(k + 1));
      if (((e >> 16) & 0xFF) != node || (e & 0xFFFF) == 0) continue;
      consumer_started[static_cast<std::size_t>(k)] = true;
      consumer_last[static_cast<std::size_t>(k)] = now;
    }
    arm_consumer();
  }

  // A guarding request: the reply (NMT state, toggle bit), and life guarding from now on.
  void on_guard_request() {
    if (!cfg.node_guarding) return;
    CanFrame r;
    r.id = kHeartbeat + n;
    r.dlc = 1;
    r.data[0] = static_cast<std::uint8_t>((guard_toggle ? 0x80 : 0x00) | (nmt_now.load() & 0x7F));
    guard_toggle = !guard_toggle;
    send(r);
    if (life_time_ms() > 0) {
      guarded = true;
      last_guard = Clock::now();
      arm_consumer();
    }
  }

  long long life_time_ms() { return cfg.node_guarding ? static_cast<long long>(get(0x100C, 0)) * get(0x100D, 0) : 0; }

  // Checks at a tenth of the shortest consumer (or life) time (1..10 ms) while anything is watched.
  void arm_consumer() {
    if (!cfg.heartbeat_consumer && !cfg.node_guarding) return;
    long long shortest = guarded ? life_time_ms() : 0;
    if (!cfg.node_guarding) {
      for (int k = 0; k < kConsumerEntries; ++k) {
        const std::uint32_t e = get(0x1016, static_cast<std::uint8_t>(k + 1));
        if (consumer_started[static_cast<std::size_t>(k)] && (e & 0xFFFF) != 0 && (shortest == 0 || (e & 0xFFFF) < shortest))
          shortest = e & 0xFFFF;
      }
    }
    if (shortest == 0 || consumer_timer.expiry() > Clock::now()) return;  // nothing to watch, or a check is due already
    consumer_timer.expires_after(std::chrono::milliseconds(std::clamp(shortest / 10, 1LL, 10LL)));
    consumer_timer.async_wait([this](const boost::system::error_code& ec) {
      if (ec) return;
      check_consumer();
      arm_consumer();
    });
  }

  void check_consumer() {
    const auto now = Clock::now();
    if (cfg.node_guarding) {
      const long long life = life_time_ms();
      if (guarded && life > 0 && now - last_guard > std::chrono::milliseconds(life)) {
        guarded = false;  // life guarding starts again with the next request
        heartbeat_event(0, now - last_guard);
      }
      return;
    }
    for (int k = 0; k < kConsumerEntries; ++k) {
      const auto i = static_cast<std::size_t>(k);
      const std::uint32_t e = get(0x1016, static_cast<std::uint8_t>(k + 1));
      if (!consumer_started[i] || (e & 0xFFFF) == 0) continue;
      if (now - consumer_last[i] <= std::chrono::milliseconds(e & 0xFFFF)) continue;
      consumer_started[i] = false;  // CiA 301: monitoring starts again with the node's next heartbeat
      heartbeat_event(static_cast<std::uint8_t>((e >> 16) & 0xFF), now - consumer_last[i]);
    }
  }

  // A heartbeat event: EMCY 0x8130 (life guard error or heartbeat error) and the abort connection
  // reaction of 0x6007 (CiA 402).
  void heartbeat_event(std::uint8_t node, Clock::duration silence) {
    const auto option = static_cast<std::int16_t>(cfg.abort_connection_option ? get(cia402::kAbortConnectionOption, 0) : 1);
    const bool powered = state == State::ready_to_switch_on || state == State::switched_on || state == State::operation_enabled ||
                         state == State::quick_stop_active;
    if (option == 1 || option < 0) {  // fault (a manufacturer-specific option: the fault, the safest)
      if (state != State::fault) enter_fault(0x8130, 0x11, {});
    } else {
      send(emcy(n, Emcy{0x8130, static_cast<std::uint8_t>(get(0x1001, 0) | 0x11), {}}));
      if (option == 2 && powered) {
        state = State::switch_on_disabled;
      } else if (option == 3 && state == State::operation_enabled) {
        const DriveModelSample smp = model.sample();
        if (cfg.quick_stop_ramp) {
          state = State::quick_stop_active;
          qs_t0 = Clock::now();
          qs_p0 = smp.position_rad;
          qs_v0 = smp.velocity_rad_s;
          qs_started = true;
          run_own_clock();
        } else {
          state = State::switch_on_disabled;
        }
      } else if (option == 3 && powered) {
        state = State::switch_on_disabled;
      }
    }
    app_step();
    last_event = Cia402DriveEmulator::ConsumerEvent{node, std::chrono::duration_cast<std::chrono::microseconds>(silence), state};
    ++consumer_events;
  }

  // A quick stop ramp with no master left to send SYNC: the drive steps itself every millisecond.
  void run_own_clock() {
    own_clock.expires_after(std::chrono::milliseconds(1));
    own_clock.async_wait([this](const boost::system::error_code& ec) {
      if (ec || state != State::quick_stop_active) return;
      app_step();
      run_own_clock();
    });
  }

  // -- receive --
  void on_frame(const CanFrame& f) {
    if (f.error || silent) return;
    if (f.id == kNmt) return on_nmt(f);
    if (f.id > kHeartbeat && f.id <= kHeartbeat + 0x7F) return on_heartbeat(f);
    if (nmt() == NmtState::stopped) return;
    if (f.id == kSdoRx + n) return on_sdo(f);
    if (nmt() != NmtState::operational) return;
    if (f.id == kSync) return on_sync();
    for (int k = 0; k < cfg.pdos; ++k) {
      const std::uint32_t cob = get(0x1400 + k, 1);
      if (!(cob & kCobIdInvalid) && f.id == (cob & 0x7FF)) return on_rpdo(k, f);
    }
  }

  void on_nmt(const CanFrame& f) {
    if (f.dlc < 2 || (f.data[1] != 0 && f.data[1] != n)) return;
    switch (static_cast<NmtCommand>(f.data[0])) {
      case NmtCommand::start: set_nmt(NmtState::operational); break;
      case NmtCommand::stop: set_nmt(NmtState::stopped); break;
      case NmtCommand::enter_pre_operational: set_nmt(NmtState::pre_operational); break;
      case NmtCommand::reset_node: boot(true); break;
      case NmtCommand::reset_communication: boot(false); break;
    }
  }

  int mapped_bytes(std::uint16_t map_index) {
    int bits = 0;
    const std::uint32_t count = get(map_index, 0);
    for (std::uint8_t s = 1; s <= count; ++s) bits += get(map_index, s) & 0xFF;
    return bits / 8;
  }

  void on_rpdo(int k, const CanFrame& f) {
    if (f.dlc < mapped_bytes(0x1600 + k)) {  // CiA 301: PDO not processed due to length error
      send(emcy(n, Emcy{0x8210, 0x11, {}}));
      return;
    }
    rpdo_data[k] = f.data;
    rpdo_pending[k] = true;
    if (get(0x1400 + k, 2) >= 0xFE) apply_rpdo(k);  // event-driven: at once
  }

  void apply_rpdo(int k) {
    rpdo_pending[k] = false;
    const std::uint16_t map = 0x1600 + k;
    int byte = 0;
    for (std::uint8_t s = 1; s <= get(map, 0); ++s) {
      const std::uint32_t e = get(map, s);
      const int bytes = (e & 0xFF) / 8;
      od.at(e >> 8).value = get_le(&rpdo_data[k][byte], bytes);
      byte += bytes;
    }
    app_step();
  }

  void on_sync() {
    ++syncs;
    bool applied = false;
    for (int k = 0; k < cfg.pdos; ++k) {
      if (rpdo_pending[k] && get(0x1400 + k, 2) <= 240) apply_rpdo(k), applied = true;
    }
    if (!applied) app_step();
    for (int k = 0; k < cfg.pdos; ++k) {
      const std::uint32_t cob = get(0x1800 + k, 1);
      const std::uint32_t type = get(0x1800 + k, 2);
      if ((cob & kCobIdInvalid) || type < 1 || type > 240) continue;  // only synchronous TPDOs are produced
      if (++tpdo_count[k] < static_cast<int>(type)) continue;
      tpdo_count[k] = 0;
      CanFrame t;
      t.id = cob & 0x7FF;
      const std::uint16_t map = 0x1A00 + k;
      for (std::uint8_t s = 1; s <= get(map, 0); ++s) {
        const std::uint32_t e = get(map, s);
        const int bytes = (e & 0xFF) / 8;
        put_le(&t.data[t.dlc], od.at(e >> 8).value, bytes);
        t.dlc = static_cast<std::uint8_t>(t.dlc + bytes);
      }
      send_late(t);
    }
  }

  // -- the drive: CiA 402 state machine and the model --
  void enter_fault(std::uint16_t code, std::uint8_t reg, const std::array<std::uint8_t, 5>& mfr) {
    state = State::fault;
    set(cia402::kErrorCode, 0, code);
    set(0x1001, 0, reg | 0x01);
    send(emcy(n, Emcy{code, static_cast<std::uint8_t>(reg | 0x01), mfr}));
  }

  void app_step() {
    const std::uint16_t cw = static_cast<std::uint16_t>(get(cia402::kControlword, 0));
    const bool reset_edge = (cw & 0x80) && !(last_cw & 0x80);
    last_cw = cw;
    DriveModelSample s = model.sample();
    if (state == State::fault && reset_edge) {
      model.reset_fault();
      s = model.sample();
      if (!s.fault) {
        state = State::switch_on_disabled;
        set(cia402::kErrorCode, 0, 0);
        set(0x1001, 0, 0);
        send(emcy(n, Emcy{}));  // error reset
      }
    } else if (s.fault && state != State::fault) {
      enter_fault(s.fault_code, 0x02, {});
    } else if (!(cw & 0x80)) {
      const bool shutdown = (cw & 0x87) == 0x06, switch_on = (cw & 0x8F) == 0x07, enable = (cw & 0x8F) == 0x0F;
      const bool disable_voltage = (cw & 0x82) == 0x00, quick_stop = (cw & 0x86) == 0x02;
      switch (state) {
        case State::not_ready_to_switch_on: state = State::switch_on_disabled; break;
        case State::switch_on_disabled:
          if (shutdown) state = State::ready_to_switch_on;
          break;
        case State::ready_to_switch_on:
          if (switch_on)
            state = State::switched_on;
          else if (enable)
            state = State::operation_enabled;
          else if (disable_voltage || quick_stop)
            state = State::switch_on_disabled;
          break;
        case State::switched_on:
          if (enable)
            state = State::operation_enabled;
          else if (shutdown)
            state = State::ready_to_switch_on;
          else if (disable_voltage || quick_stop)
            state = State::switch_on_disabled;
          break;
        case State::operation_enabled:
          if (switch_on)
            state = State::switched_on;
          else if (shutdown)
            state = State::ready_to_switch_on;
          else if (disable_voltage)
            state = State::switch_on_disabled;
          else if (quick_stop && cfg.quick_stop_ramp) {
            state = State::quick_stop_active;
            qs_t0 = Clock::now();
            qs_p0 = s.position_rad;
            qs_v0 = s.velocity_rad_s;
            qs_started = true;
          } else if (quick_stop) {
            state = State::switch_on_disabled;  // quick stop option 0: stop at once, drive function off
          }
          break;
        case State::quick_stop_active:
          if (disable_voltage) state = State::switch_on_disabled;
          break;
        case State::fault_reaction_active: state = State::fault; break;
        case State::fault: break;
      }
    }
    update_mode_display();
    const auto mode = static_cast<std::int8_t>(get(cia402::kModesDisplay, 0));
    const bool following = state == State::operation_enabled && mode == cia402::kModeCsp;
    const auto target = static_cast<std::int32_t>(get(cia402::kTargetPosition, 0));
    if (state == State::quick_stop_active) {
      // The quick stop ramp (0x6085), then switch on disabled (0x605A = 2).
      const double a = std::abs(cfg.units.to_rad(
          static_cast<std::int32_t>(std::min<std::uint32_t>(get(cia402::kQuickStopDeceleration, 0), 0x7FFFFFFF))));
      const double t = std::chrono::duration<double>(Clock::now() - qs_t0).count();
      const double t_stop = a > 0 ? std::abs(qs_v0) / a : 0.0;
      const double tt = std::min(t, t_stop);
      const double dir = qs_v0 < 0 ? -1.0 : 1.0;
      model.command(qs_p0 + qs_v0 * tt - dir * a * tt * tt / 2, true);
      if (t >= t_stop) state = State::switch_on_disabled;
    } else {
      model.command(following ? cfg.units.to_rad(target) : s.position_rad, following);
    }
    s = model.sample();
    // What the encoder reports: the motor's position, or while frozen the one it had.
    std::int32_t actual = cfg.units.to_counts(s.position_rad);
    if (!freeze_position || refreeze.exchange(false)) frozen_counts.reset();
    if (freeze_position) {
      if (!frozen_counts) frozen_counts = actual;
      actual = *frozen_counts;
      s.velocity_rad_s = 0;
    }
    if (following && cfg.following_error)
      check_following_error(target, actual);
    else
      following_out = false;
    set(cia402::kPositionActual, 0, static_cast<std::uint32_t>(actual));
    set(cia402::kVelocityActual, 0, static_cast<std::uint32_t>(cfg.units.to_counts(s.velocity_rad_s)));
    std::uint16_t sw = statusword_for(state) | 0x0200;  // remote
    if (following) sw |= 0x1000;                        // CSP: drive follows the command value
    set(cia402::kStatusword, 0, sw);
    state_now = static_cast<std::uint8_t>(state);
  }

  // 0x6061 shows the requested mode once mode_display_delay has passed since 0x6060 changed.
  void update_mode_display() {
    if (Clock::now() - mode_written >= cfg.mode_display_delay) set(cia402::kModesDisplay, 0, get(cia402::kModesOfOperation, 0));
  }

  // CiA 402 following error: |demand - actual| above 0x6065 for longer than 0x6066.
  void check_following_error(std::int32_t demand, std::int32_t actual) {
    const std::uint32_t window = get(cia402::kFollowingErrorWindow, 0);
    const long long err = static_cast<long long>(demand) - actual;
    if (window == 0xFFFFFFFF || static_cast<unsigned long long>(err < 0 ? -err : err) <= window) {
      following_out = false;
      return;
    }
    const auto now = Clock::now();
    if (!following_out) following_out = true, following_since = now;
    if (now - following_since > std::chrono::milliseconds(get(cia402::kFollowingErrorTimeout, 0))) {
      following_out = false;
      std::array<std::uint8_t, 5> mfr{};
      put_le(mfr.data(), static_cast<std::uint32_t>(static_cast<std::int32_t>(err)), 4);
      enter_fault(0x8611, 0x20, mfr);  // device profile specific (+ generic)
      model.command(cfg.units.to_rad(actual), false);
    }
  }

  // -- SDO server --
  std::uint32_t check_write(std::uint16_t index, std::uint8_t sub, std::uint32_t v) {
    const auto pdo_valid = [&](std::uint16_t comm) { return !(get(comm, 1) & kCobIdInvalid); };
    const bool rpdo_map = index >= 0x1600 && index <= 0x1603, tpdo_map = index >= 0x1A00 && index <= 0x1A03;
    if (rpdo_map || tpdo_map) {
      const std::uint16_t comm = static_cast<std::uint16_t>(rpdo_map ? index - 0x200 : index - 0x200);
      if (pdo_valid(comm)) return kAbortState;
      // An entry (index << 16 | sub << 8 | bits) must name an object this PDO can carry, whole.
      const auto entry_mappable = [&](std::uint32_t entry) {
        const auto it = od.find(entry >> 8);
        return it != od.end() && it->second.mappable && (entry & 0xFF) == it->second.size * 8u &&
               (!rpdo_map || it->second.writable);
      };
      if (sub == 0) {
        // CiA 301: the count is checked when written, against the entries it counts (an entry
        // left at 0 maps nothing: taken, the next PDO would look up an object that is not there).
        if (v > 8) return kAbortPdoLength;
        int bits = 0;
        for (std::uint8_t s = 1; s <= v; ++s) {
          const std::uint32_t entry = get(index, s);
          if (!entry_mappable(entry)) return kAbortNotMappable;
          bits += entry & 0xFF;
        }
        return bits > 64 ? kAbortPdoLength : 0;
      }
      if (get(index, 0) != 0) return kAbortState;  // CiA 301: clear the count before remapping
      return entry_mappable(v) ? 0 : kAbortNotMappable;
    }
    if ((index >= 0x1400 && index <= 0x1403) || (index >= 0x1800 && index <= 0x1803)) {
      if (sub == 1 && !(v & kCobIdInvalid) && pdo_valid(index) && (v & 0x7FF) != (get(index, 1) & 0x7FF)) {
        return kAbortValue;  // change the COB-ID of a valid PDO: invalidate it first
      }
      // A PDO on a restricted id would speak as NMT, SDO or a heartbeat to every node (a TPDO on
      // 0x000 is an NMT command); 29-bit ids this drive does not have.
      if (sub == 1 && !(v & kCobIdInvalid) && ((v & kCobIdExtended) || restricted_can_id(v & 0x7FF))) return kAbortValue;
      return 0;
    }
    if (index == 0x1016 && sub >= 1) {
      // CiA 301: one entry per node; a second with a time for a node already watched is refused.
      if ((v & 0xFFFF) == 0 || ((v >> 16) & 0xFF) == 0) return 0;
      for (int k = 1; k <= kConsumerEntries; ++k) {
        const std::uint32_t e = get(0x1016, static_cast<std::uint8_t>(k));
        if (k != sub && (e & 0xFFFF) != 0 && ((e >> 16) & 0xFF) == ((v >> 16) & 0xFF)) return kAbortIncompatible;
      }
      return 0;
    }
    if (index == cia402::kAbortConnectionOption) {
      const auto o = static_cast<std::int16_t>(v);
      return o <= 3 ? 0 : kAbortValue;  // 0..3, or manufacturer-specific (negative)
    }
    if (index == cia402::kModesOfOperation) {
      const auto m = static_cast<std::int8_t>(v);
      return m == cia402::kModeCsp || m == 0 ? 0 : kAbortValue;
    }
    return 0;
  }

  void on_sdo(const CanFrame& f) {
    if (f.dlc < 8) return;  // not an SDO request: ignore, as drives do
    const std::uint8_t cs = f.data[0];
    const auto index = static_cast<std::uint16_t>(get_le(&f.data[1], 2));
    const std::uint8_t sub = f.data[3];
    const auto abort = [&](std::uint32_t code) { send_late(sdo_abort(n, index, sub, code, true)); };
    if ((cs >> 5) == 4) return;  // the client aborted: nothing to clean up for expedited transfers
    if (auto fail = sdo_failures.find(key(index, sub)); fail != sdo_failures.end()) return abort(fail->second);
    const auto it = od.find(key(index, sub));
    if (it == od.end()) {
      const bool index_exists = od.lower_bound(key(index, 0)) != od.end() && (od.lower_bound(key(index, 0))->first >> 8) == index;
      return abort(index_exists ? kAbortNoSub : kAbortNoObject);
    }
    Obj& o = it->second;
    if (index == cia402::kModesDisplay) update_mode_display();
    if (cs == 0x40) return send_late(sdo_upload_ok(n, index, sub, o.value, o.size));
    if ((cs >> 5) != 1) return abort(kAbortCommand);
    if (!(cs & 0x02)) return abort(kAbortCommand);  // segmented download: not supported here
    if (!o.writable) return abort(kAbortReadOnly);
    const int size = (cs & 0x01) ? 4 - ((cs >> 2) & 0x03) : o.size;
    if (size != o.size) return abort(kAbortLength);
    const std::uint32_t v = get_le(&f.data[4], size);
    if (const std::uint32_t code = check_write(index, sub, v)) return abort(code);
    if (index == cia402::kModesOfOperation && v != o.value) mode_written = Clock::now();
    o.value = v;
    if (index == 0x1017) arm_heartbeat();
    if (index == 0x1016 && sub >= 1) consumer_started[static_cast<std::size_t>(sub - 1)] = false;  // from its next heartbeat
    if (index == cia402::kControlword || index == cia402::kModesOfOperation || index == cia402::kTargetPosition) app_step();
    send_late(sdo_download_ok(n, index, sub));
  }

  void arm_flood() {
    flood_timer.expires_after(std::chrono::milliseconds(1));
    flood_timer.async_wait([this](const boost::system::error_code& ec) {
      if (ec || flood_per_ms <= 0) return;
      CanFrame f;
      f.id = flood_id;
      f.extended = flood_id > 0x7FF;
      f.dlc = 8;
      f.data.fill(0xFF);
      for (int i = 0; i < flood_per_ms; ++i) send(f);
      arm_flood();
    });
  }

  template <class Fn>
  auto on_io(Fn fn) {
    std::packaged_task<decltype(fn())()> task(std::move(fn));
    auto fut = task.get_future();
    asio::post(io, [&task] { task(); });
    return fut.get();
  }
};

Cia402DriveEmulator::Cia402DriveEmulator(Cia402EmulatorConfig config, DriveModel& model, CanTransportFactory transport)
    : impl_(std::make_unique<Impl>(std::move(config), model)) {
  auto& m = *impl_;
  if (!transport) transport = SocketCanTransport::factory(m.cfg.interface);
  const std::uint32_t n = m.n;
  m.tr = transport(m.io, {{kNmt, 0x7FF},
                          {kSync, 0x7FF},
                          {kHeartbeat, 0x780},  // 0x700..0x77F: the heartbeats 0x1016 may name
                          {kSdoRx + n, 0x7FF},
                          {kRpdo1 + n, 0x7FF},
                          {kRpdo1 + 0x100 + n, 0x7FF},
                          {kRpdo1 + 0x200 + n, 0x7FF},
                          {kRpdo1 + 0x300 + n, 0x7FF}});
  m.tr->start([&m](const CanFrame& f) { m.on_frame(f); });
  asio::post(m.io, [&m] { m.boot(true); });
  m.thread = std::thread([&m] { m.io.run(); });
}

Cia402DriveEmulator::~Cia402DriveEmulator() {
  auto& m = *impl_;
  asio::post(m.io, [&m] {
    m.tr->stop();
    m.hb_timer.cancel();
    m.flood_timer.cancel();
    m.consumer_timer.cancel();
    m.own_clock.cancel();
  });
  m.work.reset();
  m.io.stop();
  if (m.thread.joinable()) m.thread.join();
}

canopen::NmtState Cia402DriveEmulator::nmt_state() const { return impl_->nmt(); }
cia402::State Cia402DriveEmulator::state() const { return static_cast<State>(impl_->state_now.load()); }
std::uint64_t Cia402DriveEmulator::syncs_seen() const { return impl_->syncs.load(); }

std::optional<std::uint32_t> Cia402DriveEmulator::object(std::uint16_t index, std::uint8_t sub) {
  auto& m = *impl_;
  return m.on_io([&m, index, sub]() -> std::optional<std::uint32_t> {
    const auto it = m.od.find(key(index, sub));
    if (it == m.od.end()) return std::nullopt;
    return it->second.value;
  });
}

std::optional<Cia402DriveEmulator::RampStart> Cia402DriveEmulator::quick_stop_ramp_start() {
  auto& m = *impl_;
  return m.on_io([&m]() -> std::optional<RampStart> {
    if (!m.qs_started) return std::nullopt;
    return RampStart{m.qs_p0, m.qs_v0};
  });
}

std::uint64_t Cia402DriveEmulator::heartbeat_consumer_events() const { return impl_->consumer_events.load(); }

std::optional<Cia402DriveEmulator::ConsumerEvent> Cia402DriveEmulator::last_consumer_event() {
  auto& m = *impl_;
  return m.on_io([&m] { return m.last_event; });
}

void Cia402DriveEmulator::stop_heartbeat(bool stopped) { impl_->hb_stopped = stopped; }
void Cia402DriveEmulator::set_silent(bool silent) { impl_->silent = silent; }
void Cia402DriveEmulator::freeze_position(bool frozen) {
  // Each freeze holds the position of the first SYNC after it, not one a former freeze took (a
  // freeze, a clear and a freeze with no SYNC between, as between two runs, held the old one).
  if (frozen) impl_->refreeze = true;
  impl_->freeze_position = frozen;
}
void Cia402DriveEmulator::set_response_delay(std::chrono::microseconds delay) { impl_->delay_us = delay.count(); }

void Cia402DriveEmulator::raise_emcy(std::uint16_t code, std::uint8_t error_register, std::array<std::uint8_t, 5> mfr) {
  auto& m = *impl_;
  asio::post(m.io, [&m, code, error_register, mfr] {
    m.enter_fault(code, error_register, mfr);
    m.app_step();
  });
}

void Cia402DriveEmulator::fail_sdo(std::uint16_t index, std::uint8_t sub, std::uint32_t abort_code) {
  auto& m = *impl_;
  m.on_io([&m, index, sub, abort_code] {
    m.sdo_failures[key(index, sub)] = abort_code;
    return 0;
  });
}

void Cia402DriveEmulator::clear_sdo_failures() {
  auto& m = *impl_;
  m.on_io([&m] {
    m.sdo_failures.clear();
    return 0;
  });
}

void Cia402DriveEmulator::flood(bool on, std::uint32_t id, int frames_per_ms) {
  auto& m = *impl_;
  asio::post(m.io, [&m, on, id, frames_per_ms] {
    m.flood_id = id;
    m.flood_per_ms = on ? frames_per_ms : 0;
    if (on)
      m.arm_flood();
    else
      m.flood_timer.cancel();
  });
}

void Cia402DriveEmulator::emulate_bus_error(EmulatedBusError kind) {
  auto& m = *impl_;
  asio::post(m.io, [&m, kind] { m.send(make_error_frame(kind)); });
}

void Cia402DriveEmulator::reboot() {
  auto& m = *impl_;
  asio::post(m.io, [&m] { m.boot(true); });
}

}  // namespace hil::drv
