// The CiA 402 drive emulator's state and its I/O thread (private to drivers/src): NMT, SYNC and
// the PDOs, the heartbeat producer and consumer, node guarding, the CiA 402 state machine over the
// model, the fault API's hooks. Its object dictionary and SDO server are cia402_emulator_sdo.cpp;
// its configuration and public API cia402_emulator.cpp.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <cmath>
#include <future>
#include <map>
#include <memory>
#include <optional>
#include <thread>

#include "hil/drv/cia402_emulator.hpp"

namespace hil::drv {

namespace asio = boost::asio;
// Inside the emulator's files only: the CANopen codec's names unqualified.
using namespace canopen;
using cia402::State;

namespace emulator_detail {
constexpr std::uint32_t key(std::uint16_t index, std::uint8_t sub) { return (std::uint32_t{index} << 8) | sub; }

inline constexpr std::uint32_t kAbortNoObject = 0x06020000, kAbortNoSub = 0x06090011, kAbortReadOnly = 0x06010002,
                               kAbortLength = 0x06070010, kAbortCommand = 0x05040001, kAbortState = 0x08000022,
                               kAbortNotMappable = 0x06040041, kAbortPdoLength = 0x06040042, kAbortValue = 0x06090030,
                               kAbortIncompatible = 0x06040043;
inline constexpr int kConsumerEntries = 4;  // 0x1016:01..04

inline std::uint16_t statusword_for(State s) {
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
}  // namespace emulator_detail

using namespace emulator_detail;

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

  // The object dictionary (cia402_emulator_sdo.cpp): the communication objects as after a reset
  // communication (PDOs, heartbeat or guarding, identity), the drive's as after a reset application.
  void reset_communication();
  void reset_application();

  // The SDO server (cia402_emulator_sdo.cpp): what a write would break, as the abort code to
  // answer (0: taken); a request on 0x600 + node, answered after the response delay.
  std::uint32_t check_write(std::uint16_t index, std::uint8_t sub, std::uint32_t v);
  void on_sdo(const CanFrame& f);

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

}  // namespace hil::drv
