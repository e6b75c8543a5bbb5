// The CiA 402 client's state and its I/O thread's side (private to drivers/src): receiving
// (heartbeat, TPDO1, EMCY, error frames; SDO replies go to the SdoClient), the cyclic tick (RPDO1
// then SYNC), the bench's heartbeat, node guarding and the heartbeat consumer. The setup calls
// (configure sequence, activate, deactivate) are in cia402_drive.cpp.
#pragma once

#include <sys/eventfd.h>
#include <unistd.h>

#include <atomic>
#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/posix/stream_descriptor.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "hil/drv/cia402_drive.hpp"
#include "hil/drv/sdo_client.hpp"
#include "setup_util.hpp"

namespace hil::drv {

namespace asio = boost::asio;

// Inside the client's files only: the CANopen codec's names and milliseconds unqualified.
using namespace canopen;
using std::chrono::milliseconds;

struct Cia402Drive::Impl {
  Cia402Config cfg;
  std::string who;  // "CiA 402 drive node 5 on vcan0"
  std::uint8_t n;
  asio::io_context io;
  asio::executor_work_guard<asio::io_context::executor_type> work{io.get_executor()};
  std::unique_ptr<CanTransport> tr;
  asio::steady_timer sync_timer{io}, hb_timer{io}, bus_timer{io}, bench_hb_timer{io}, guard_timer{io};
  int kick_fd = -1;
  asio::posix::stream_descriptor kick{io};
  std::uint64_t kick_buf = 0;
  std::thread thread;

  // Shared with other threads.
  // The newest command and which write() it came with (0: from a setup call).
  struct NumberedCommand {
    DriveCommand command;
    std::uint64_t write = 0;
  };
  Mailbox<NumberedCommand> command;
  std::atomic<std::uint64_t> writes{0};      // write() calls (one writing thread: the loop)
  std::atomic<std::uint64_t> sent_write{0};  // the write() whose command the last SYNC carried
  Mailbox<DriveFeedback> feedback;
  Mailbox<DeviceHealth> health_box;
  std::atomic<std::uint8_t> target{static_cast<std::uint8_t>(cia402::Target::disabled)};
  std::atomic<std::uint8_t> state_now{static_cast<std::uint8_t>(cia402::State::not_ready_to_switch_on)};
  // An explicit request (activate(), reset_fault(), a fault_reset edge in the command): it
  // acknowledges the fault latched now and resets the drive's if it is in fault, once.
  std::atomic<bool> reset_request{false};
  // Set when the drive enters fault or the client latches one (heartbeat lost, rebooted, left NMT
  // operational, position jump); cleared only by a reset request or configure(). While set the
  // enable sequence stops: quick stop from operation enabled, disable voltage elsewhere. Without
  // it a drive that left fault by any other way (a reset from another master, a drive clearing
  // its own fault) was walked straight back to operation enabled.
  std::atomic<bool> fault_hold{false};
  std::atomic<std::uint64_t> bootups{0};
  std::atomic<std::uint8_t> nmt_now{0xFF};
  // The newest TPDO1 was too short to use: the feedback is stale although TPDOs arrive, and the
  // stale reason must say so rather than "no TPDO".
  std::atomic<bool> tpdo_malformed{false};
  // The loop's liveness (cfg.loop_hang_bound): write() stores when it ran, as the steady clock's
  // count; 0 while no loop runs the drive. One atomic word: no lock on the loop's side.
  std::atomic<Clock::rep> loop_write_count{0};
  std::vector<std::string> notes;  // configure(): optional objects the drive lacks (setup thread only)
  // Set by cancel_setup(), for good: a client whose setup was cancelled is being given up.
  std::atomic<bool> setup_cancelled{false};
  const char* setup_call = nullptr;  // the setup call in progress (setup thread only)

  // I/O thread only.
  DeviceHealth h;
  DriveFeedback fb;
  BusStateTracker bus;
  bool pdo_running = false;
  bool expect_heartbeat = false;
  bool bench_heartbeat_on = false;  // the bench's own heartbeat is produced (from configure() on)
  bool guarding = false;            // node guarding requests are sent (a drive without 0x1017)
  bool rebooted = false;
  // Set by the first heartbeat saying operational after configure(); a later heartbeat in any
  // other state means the drive stopped processing PDOs (another master's NMT stop, a drive
  // that fell back to pre-operational): latched as a fault until configure(), as a reboot is.
  bool seen_operational = false;
  bool left_operational = false;
  bool bus_off_latched = false;
  bool prev_cmd_reset = false;
  bool was_drive_fault = false;  // the drive's fault as of the last publish(): fault_hold latches on its rising edge
  bool reset_pending = false;    // a reset request found the drive in fault: send the 0 -> 1 edge of bit 7
  // 0x6064 moved further in one TPDO than the drive can (an int32 wrap of the count, a corrupt
  // frame): latched, with the last trusted position kept, until configure().
  bool position_jump = false;
  // configure()'s SDO read of 0x6064 and the time just before it was asked: the first TPDO after
  // NMT start is checked against it. Without it the first TPDO's position was taken unchecked, so
  // a corrupt or wrapped first count became the position the loop holds and starts from.
  bool position_read_valid = false;
  Clock::time_point position_read_time{};
  std::uint16_t last_cw = 0;
  std::int32_t last_pos_counts = 0;
  std::int32_t last_target_counts = 0;  // the target in the last RPDO1
  bool bad_target_reported = false;
  Clock::time_point last_sync{};
  std::string last_emcy_text;  // the newest EMCY decoded, kept for the fault message
  // The loop was taken for hung (latched until configure()): the bench's heartbeat and guarding
  // requests stop, fault_hold sends quick stop. loop_last_write: its last write() before.
  bool loop_hung = false;
  bool loop_hang_measured = false;  // the loop came back: the hang's length is in the fault cause
  Clock::time_point loop_last_write{};
  // EMCY 0x8130 while the drive watches the bench: it lost the bench's heartbeat (or life
  // guarding) and did its 0x6007 reaction; latched, or the enable sequence walked it back on.
  bool drive_lost_bench = false;
  // The bench's heartbeat as it went out: the last one and the longest gap between two (a host
  // that stalled the whole process), measured on the bench's own clock.
  Clock::time_point bench_hb_sent{};
  Clock::duration bench_hb_gap_max{};
  // Switching off (cia402_drive_off.cpp): the last switch-off's record and the thread the I/O
  // thread starts for one it asks for itself (the SDO path blocks, the I/O thread must not).
  std::mutex off_mutex;
  SwitchOff off;
  std::thread off_thread;
  std::atomic<bool> off_busy{false};
  // The SDO client on this channel (configure's object writes, sdo_read/sdo_write, the probe).
  std::unique_ptr<SdoClient> sdo;

  explicit Impl(Cia402Config c) : cfg(std::move(c)), n(cfg.node_id) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "CiA 402 drive node %u on %s", n, cfg.interface.c_str());
    who = buf;
    h.heartbeat_timeout = cfg.heartbeat_timeout;
    sdo = std::make_unique<SdoClient>(
        io, SdoClient::Settings{.node_id = n, .who = who, .timeout = cfg.sdo_timeout, .retries = cfg.sdo_retries}, h,
        SdoClient::Link{.send = [this](const CanFrame& f) { return send(f); },
                        .error = [this](const std::string& text) { error(text); },
                        .publish = [this] { publish(); },
                        .check_cancelled = [this] { throw_if_cancelled(); }});
  }

  // -- setup calls (the calling thread) --
  // Marks configure() or activate() as in progress for as long as it lives: cancel_setup() ends it,
  // or refuses it from the start.
  class SetupCall {
   public:
    SetupCall(Impl& m, const char* name) : m_(m) {
      m_.setup_call = name;
      try {
        m_.throw_if_cancelled();
      } catch (...) {
        m_.setup_call = nullptr;  // no destructor runs for a constructor that throws
        throw;
      }
    }
    ~SetupCall() { m_.setup_call = nullptr; }
    SetupCall(const SetupCall&) = delete;
    SetupCall& operator=(const SetupCall&) = delete;

   private:
    Impl& m_;
  };

  void throw_if_cancelled() const {
    if (setup_call != nullptr && setup_cancelled) throw DriveError(who + ": " + setup_call + " cancelled");
  }

  // detail::wait_for, ended by cancel_setup() within one poll.
  template <class Pred>
  bool wait_for(milliseconds timeout, Pred pred) const {
    return detail::wait_for(timeout, [&] {
      throw_if_cancelled();
      return pred();
    });
  }

  // -- publishing (I/O thread) --
  void error(const std::string& text) { h.set_last_error(text); }

  void publish() {
    const auto st = cia402::decode_statusword(fb.statusword);
    const bool drive_fault = fb.valid && (st == cia402::State::fault || st == cia402::State::fault_reaction_active);
    const bool client_fault = h.heartbeat_lost || rebooted || left_operational || position_jump || loop_hung || drive_lost_bench;
    // The drive's fault latches on its edge only: after a requested reset the drive still shows
    // fault for a SYNC or two, which must not latch the hold again. Bus-off is left to its
    // policy: `wait` and `recover` resume by configuration, and the drive never saw a fault.
    if ((drive_fault && !was_drive_fault) || client_fault) {
      // The first cause is kept: the message that latched it is the newest error now.
      if (!fault_hold.exchange(true) || h.fault_cause[0] == '\0') h.fault_cause = h.last_error;
    }
    if (!fault_hold) h.fault_cause[0] = '\0';
    was_drive_fault = drive_fault;
    // The hold is a fault until it is reset: a heartbeat that came back clears heartbeat_lost, but
    // the client still holds the drive in quick stop, and the rig must see why (not a drive that
    // "switched itself off" with no fault).
    h.fault = drive_fault || client_fault || bus_off_latched || fault_hold;
    h.connected = expect_heartbeat && !h.heartbeat_lost && h.bus_state != BusState::bus_off;
    h.statusword = fb.statusword;
    fb.fault = h.fault;
    fb.enabled = fb.valid && st == cia402::State::operation_enabled;
    feedback.store(fb);
    health_box.store(h);
  }

  bool send(const CanFrame& f) {
    if (tr->send(f)) {
      ++h.tx_frames;
      return true;
    }
    ++h.tx_failed;
    return false;
  }

  // -- receive --
  void on_frame(const CanFrame& f) {
    if (f.error) {
      on_error_frame(f);
    } else {
      ++h.rx_frames;
      if (f.id == kHeartbeat + n)
        on_heartbeat(f);
      else if (f.id == kTpdo1 + n)
        on_tpdo(f);
      else if (f.id == kSdoTx + n)
        sdo->on_reply(f);
      else if (f.id == kEmcy + n)
        on_emcy(f);
    }
    publish();
  }

  void malformed(const CanFrame& f, const char* what) {
    ++h.malformed;
    error(who + ": malformed " + what + " " + to_string(f));
  }

  void on_heartbeat(const CanFrame& f) {
    if (f.dlc < 1 || f.rtr) return malformed(f, "heartbeat");
    const std::uint8_t s = f.data[0] & 0x7F;
    h.nmt_state = s;
    nmt_now = s;
    const Clock::time_point lost_since = h.last_heartbeat;
    h.last_heartbeat = f.rx_time;
    if (h.heartbeat_lost) {
      h.heartbeat_lost = false;
      const auto gap = std::chrono::duration_cast<milliseconds>(f.rx_time - lost_since).count();
      error(who + ": heartbeat resumed after " + std::to_string(gap) + " ms" +
            (fault_hold ? "; the drive stays held (quick stop) until a fault reset" : ""));
    }
    if (s == static_cast<std::uint8_t>(NmtState::boot_up)) {
      ++bootups;
      if (pdo_running) {  // it rebooted behind our back: its PDO mapping is gone
        rebooted = true;
        pdo_running = false;
        error(who + ": the drive rebooted (boot-up message); configure() again");
      }
    } else if (pdo_running && s == static_cast<std::uint8_t>(NmtState::operational)) {
      seen_operational = true;
    } else if (pdo_running && seen_operational && !left_operational) {
      // Not operational any more: its TPDOs stopped and it ignores our RPDOs. Without this the
      // run would only see stale feedback and trip on the watchdog, for the wrong reason.
      left_operational = true;
      char state[8];
      std::snprintf(state, sizeof state, "0x%02X", s);
      const std::string stall = bench_stall_note(f.rx_time);
      error(who + ": the drive left NMT operational (heartbeat says " + std::string(to_string(static_cast<NmtState>(s))) + ", " +
            state + ")" + (stall.empty() ? "; it no longer processes PDOs; configure() again" : stall));
      // PDOs no longer carry the controlword: the drive is switched off by SDO (or NMT stop).
      if (target.load() != static_cast<std::uint8_t>(cia402::Target::disabled))
        start_switch_off("the drive left NMT operational");
    }
  }

  void on_tpdo(const CanFrame& f) {
    if (f.dlc < 6 || f.rtr) {
      tpdo_malformed = true;
      return malformed(f, "TPDO1 (expected 6 bytes: statusword, position actual)");
    }
    tpdo_malformed = false;
    ++h.pdo_received;
    fb.statusword = static_cast<std::uint16_t>(get_le(&f.data[0], 2));
    const auto counts = static_cast<std::int32_t>(get_le(&f.data[2], 4));
    if (!position_jump && (fb.valid || position_read_valid)) {
      check_position_step(counts, f.rx_time, fb.valid ? fb.rx_time : position_read_time);
    }
    if (!position_jump) {
      last_pos_counts = counts;
      fb.position_rad = cfg.units.to_rad(counts);
    }
    fb.valid = true;
    fb.rx_time = f.rx_time;
    ++fb.sequence;
    const auto st = cia402::decode_statusword(fb.statusword);
    if (static_cast<std::uint8_t>(st) != state_now.load()) {
      // The EMCY that announced the fault (if one came first) stays in the message.
      if (st == cia402::State::fault) {
        error(who + ": drive entered fault" + (last_emcy_text.empty() ? std::string() : ": " + last_emcy_text));
      }
      state_now = static_cast<std::uint8_t>(st);
    }
  }

  static constexpr std::int64_t kHalfInt32Range = std::int64_t{1} << 31;

  // The most 0x6064 may move between two TPDOs arriving `gap` apart: twice what the configured
  // max profile velocity covers in that gap plus one SYNC period of jitter; without that limit,
  // half the int32 range, beyond which the step can only be a wrap of the count.
  std::int64_t max_position_step_counts(Clock::duration gap) const {
    const double v_rad_s = cfg.limits.max_profile_velocity_rad_s;
    if (v_rad_s <= 0) return kHalfInt32Range;
    const double span_s =
        std::chrono::duration<double>(std::max<Clock::duration>(gap, cfg.sync_period) + cfg.sync_period).count();
    const double counts = 2.0 * v_rad_s * span_s / std::abs(cfg.units.rad_per_count()) + 1.0;
    return counts >= static_cast<double>(kHalfInt32Range) ? kHalfInt32Range : static_cast<std::int64_t>(counts);
  }

  // `since`: when last_pos_counts was true (the previous TPDO, or just before configure()'s read).
  void check_position_step(std::int32_t counts, Clock::time_point rx_time, Clock::time_point since) {
    const Clock::duration gap = rx_time - since;
    const std::int64_t step = std::int64_t{counts} - last_pos_counts;
    const std::int64_t limit = max_position_step_counts(gap);
    if (step <= limit && -step <= limit) return;
    position_jump = true;
    // Kept short: last_error holds 191 characters, the drive's name included.
    char text[160];
    std::snprintf(text, sizeof text,
                  ": position jump: 0x6064 from %d to %d counts in %.1f ms, over the %lld it can move%s; configure()",
                  last_pos_counts, counts, std::chrono::duration<double, std::milli>(gap).count(), static_cast<long long>(limit),
                  step > kHalfInt32Range || -step > kHalfInt32Range ? " (int32 wrap)" : "");
    error(who + text);
  }

  void on_emcy(const CanFrame& f) {
    const auto e = parse_emcy(f);
    if (!e) return malformed(f, "EMCY (expected 8 bytes)");
    ++h.emcy_count;
    h.last_emcy_code = e->error_code;
    h.last_emcy_register = e->error_register;
    last_emcy_text = e->error_code == 0 ? std::string() : describe(*e);
    if (e->error_code == 0x8130 && pdo_running && (bench_heartbeat_on || guarding)) {
      // The drive's consumer (or life guarding) gave up on the bench and did its 0x6007 reaction:
      // latched as the cause, with the bench's own heartbeat gap when it was the bench that stalled.
      drive_lost_bench = true;
      const std::string stall = bench_stall_note(f.rx_time);
      static constexpr const char* kReaction[] = {"none", "fault", "disable voltage", "quick stop"};
      const auto on_loss = cfg.bench_heartbeat.on_loss;
      const std::string cause = who + ": EMCY 0x8130: the drive lost the bench's " + (guarding ? "life guarding" : "heartbeat") +
                                " and did its 0x6007 reaction (" +
                                (on_loss >= 0 && on_loss <= 3 ? kReaction[on_loss] : "its own") + ")" +
                                (stall.empty() ? ", though the bench's heartbeat went out on time" : stall);
      if (!fault_hold.exchange(true) || h.fault_cause[0] == '\0') {
        std::snprintf(h.fault_cause.data(), h.fault_cause.size(), "%s", cause.c_str());
      }
      error(who + ": " + describe(*e));  // the frame itself; fault_cause says what it means here
      return;
    }
    const bool in_fault = fb.valid && cia402::decode_statusword(fb.statusword) == cia402::State::fault;
    error(who + ": " + (in_fault && e->error_code != 0 ? "drive in fault: " : "") + describe(*e));
  }

  void on_error_frame(const CanFrame& f) {
    ++h.error_frames;
    const auto info = decode_error_frame(f);
    const BusState before = bus.state();
    bus.update(info);
    h.bus_state = bus.state();
    error(who + ": bus: " + info.text);
    if (h.bus_state == BusState::bus_off && before != BusState::bus_off) {
      bus_off_latched = true;
      if (cfg.bus_off_policy == BusOffPolicy::recover) {
        bus_timer.expires_after(cfg.bus_off_recover_after);
        bus_timer.async_wait([this](const boost::system::error_code& ec) {
          if (ec) return;
          try {
            tr->reopen();
          } catch (const std::exception& e) {
            error(e.what());
            publish();
            return;
          }
          bus.reset();
          h.bus_state = BusState::error_active;
          resume_after_bus_off("channel reopened after bus-off (policy recover)");
        });
      }
    } else if (before == BusState::bus_off && h.bus_state == BusState::error_active && bus_off_latched &&
               cfg.bus_off_policy == BusOffPolicy::wait) {
      resume_after_bus_off("controller restarted after bus-off (policy wait)");
    }
  }

  void resume_after_bus_off(const std::string& why) {
    bus_off_latched = false;
    ++h.reconnects;
    h.last_heartbeat = Clock::now();  // the bus was down; give the heartbeat a fresh timeout
    error(who + ": " + why);
    publish();
  }

  // -- SYNC and RPDO --
  void tick() {
    last_sync = Clock::now();
    if (!pdo_running || bus_off_latched) return;
    const NumberedCommand numbered = command.load();
    const DriveCommand& cmd = numbered.command;
    if (cmd.fault_reset && !prev_cmd_reset) reset_request = true;
    prev_cmd_reset = cmd.fault_reset;
    const auto st = fb.valid ? cia402::decode_statusword(fb.statusword) : cia402::State::not_ready_to_switch_on;
    // A request is used now or dropped: one made while the drive was healthy must not stay armed
    // and reset the next fault the moment it came, unasked.
    if (reset_request.exchange(false)) {
      fault_hold = false;
      reset_pending = st == cia402::State::fault;
    }
    auto tgt = static_cast<cia402::Target>(target.load());
    if (tgt == cia402::Target::operation_enabled && !cmd.enable) tgt = cia402::Target::switched_on;
    if (fault_hold) tgt = cia402::Target::quick_stop;
    // A fault reset is the 0 -> 1 edge of bit 7, so only after a controlword with bit 7 low.
    const bool reset = reset_pending && st == cia402::State::fault && !(last_cw & cia402::kCwFaultReset);
    const std::uint16_t cw = cia402::next_controlword(st, tgt, reset);
    if (cw == cia402::kCwFaultReset || st != cia402::State::fault) reset_pending = false;
    // Until enabled, the target follows the actual position so that enabling does not jump.
    // A NaN or infinite target holds the last one: to_counts() would make it INT32_MIN or
    // INT32_MAX counts, a full-speed move to the end of the encoder range.
    std::int32_t pos = last_pos_counts;
    if (st == cia402::State::operation_enabled && tgt == cia402::Target::operation_enabled) {
      if (std::isfinite(cmd.target_position_rad)) {
        pos = cfg.units.to_counts(cmd.target_position_rad);
        bad_target_reported = false;
      } else {
        pos = last_target_counts;
        if (!bad_target_reported) {
          bad_target_reported = true;
          error(who + ": target position is not a number; the last target is held");
          publish();
        }
      }
    }
    last_target_counts = pos;
    CanFrame rpdo;
    rpdo.id = kRpdo1 + n;
    rpdo.dlc = 6;
    put_le(&rpdo.data[0], cw, 2);
    put_le(&rpdo.data[2], static_cast<std::uint32_t>(pos), 4);
    send(rpdo);
    send(canopen::sync());
    sent_write.store(numbered.write, std::memory_order_release);
    last_cw = cw;
    ++h.sync_sent;
  }

  void arm_sync_timer() {
    sync_timer.expires_at(sync_timer.expiry() + cfg.sync_period);
    if (sync_timer.expiry() < Clock::now() - cfg.sync_period) sync_timer.expires_after(cfg.sync_period);
    sync_timer.async_wait([this](const boost::system::error_code& ec) {
      if (ec) return;
      // A timer this late means the I/O thread itself was stopped (the whole process stalled, not
      // the loop alone): the loop gets the next period to show it is alive before it is judged.
      const auto now = Clock::now();
      if (now - sync_timer.expiry() < cfg.loop_hang_bound / 2) check_loop(now);
      // With sync_source loop the loop's write() drives SYNC; the timer only keeps it alive
      // while no loop runs (during configure/activate, or a stalled loop).
      if (cfg.sync_source == Cia402Config::SyncSource::timer || Clock::now() - last_sync > 2 * cfg.sync_period) {
        tick();
      }
      arm_sync_timer();
    });
  }

  void arm_kick() {
    kick.async_read_some(asio::buffer(&kick_buf, sizeof kick_buf), [this](const boost::system::error_code& ec, std::size_t) {
      if (ec) return;
      tick();
      arm_kick();
    });
  }

  // -- the bench's own heartbeat (the drive consumes it: 0x1016) --
  void start_bench_heartbeat() {
    if (bench_heartbeat_on) return;
    bench_heartbeat_on = true;
    bench_hb_timer.expires_after(milliseconds(0));
    arm_bench_heartbeat();
  }

  void arm_bench_heartbeat() {
    bench_hb_timer.async_wait([this](const boost::system::error_code& ec) {
      if (ec) return;
      // While bus-off nothing goes out (as SYNC and RPDO); the drive's consumer then acts as on a dead
      // bench. Nor while the loop is hung: the heartbeat says the control loop is alive.
      const auto now = Clock::now();
      if (now - bench_hb_timer.expiry() < cfg.loop_hang_bound / 2) check_loop(now);  // as in the SYNC timer
      if (!bus_off_latched && !loop_hung && send(canopen::heartbeat(cfg.bench_heartbeat.node_id, NmtState::operational))) {
        if (bench_hb_sent != Clock::time_point{}) bench_hb_gap_max = std::max(bench_hb_gap_max, now - bench_hb_sent);
        bench_hb_sent = now;
      }
      bench_hb_timer.expires_at(bench_hb_timer.expiry() + cfg.bench_heartbeat.producer);
      if (bench_hb_timer.expiry() < Clock::now()) bench_hb_timer.expires_after(milliseconds(0));  // late: at once, no burst
      arm_bench_heartbeat();
    });
  }

  // -- node guarding (a drive without 0x1017): a remote frame on 0x700 + node every guard time --
  void start_guarding() {
    if (guarding) return;
    guarding = true;
    guard_timer.expires_after(milliseconds(0));
    arm_guard();
  }

  void arm_guard() {
    guard_timer.async_wait([this](const boost::system::error_code& ec) {
      if (ec) return;
      if (Clock::now() - guard_timer.expiry() < cfg.loop_hang_bound / 2) check_loop(Clock::now());  // as in the SYNC timer
      if (!bus_off_latched && !loop_hung) {
        CanFrame r;
        r.id = kHeartbeat + n;
        r.rtr = true;
        r.dlc = 1;  // the reply's length
        send(r);
      }
      guard_timer.expires_at(guard_timer.expiry() + cfg.node_guarding.guard_time);
      if (guard_timer.expiry() < Clock::now()) guard_timer.expires_after(milliseconds(0));
      arm_guard();
    });
  }

  // -- heartbeat consumer --
  void arm_hb_timer() {
    const auto check = std::max(milliseconds(5), std::min(milliseconds(50), cfg.heartbeat_timeout / 4));
    hb_timer.expires_after(check);
    hb_timer.async_wait([this, check](const boost::system::error_code& ec) {
      if (ec) return;
      // Late by more than a check: the I/O thread itself was stopped (a stalled host), and the
      // heartbeats that came meanwhile wait in the socket: read them before judging the drive.
      if (Clock::now() - hb_timer.expiry() > check) return arm_hb_timer();
      if (expect_heartbeat && !h.heartbeat_lost && Clock::now() - h.last_heartbeat > cfg.heartbeat_timeout) {
        h.heartbeat_lost = true;
        error(who + ": heartbeat lost (none for " + std::to_string(cfg.heartbeat_timeout.count()) + " ms)");
        publish();
      }
      arm_hb_timer();
    });
  }

  // -- the loop's liveness and the bench's own stalls --
  static long long ms_of(Clock::duration d) noexcept { return std::chrono::duration_cast<milliseconds>(d).count(); }
  // How long the drive may go without the bench's heartbeat (0x1016), or life guarding's time.
  milliseconds drive_watch_time() const {
    return guarding ? cfg.node_guarding.guard_time * cfg.node_guarding.life_time_factor : cfg.bench_heartbeat.drive_timeout;
  }

  // "; the bench's heartbeat was 1122 ms late (0x1016 gives the drive 500 ms): the host stalled"
  // when the longest gap of the bench's own heartbeat (or the one open now, at `now`) exceeded the
  // time the drive gives it; "" when it went out on time. A drive's reaction to a lost bench is
  // then the bench's doing, not the drive's.
  std::string bench_stall_note(Clock::time_point now) const {
    if (!bench_heartbeat_on && !guarding) return {};
    if (loop_hung) return "; the bench stopped its heartbeat: its control loop hung";
    Clock::duration gap = bench_hb_gap_max;
    if (bench_hb_sent != Clock::time_point{} && now > bench_hb_sent) gap = std::max(gap, now - bench_hb_sent);
    if (guarding || gap <= drive_watch_time()) return {};
    return "; the bench's heartbeat was " + std::to_string(ms_of(gap)) + " ms late (0x1016 gives the drive " +
           std::to_string(drive_watch_time().count()) + " ms): the host stalled";
  }

  // Every SYNC period and before each heartbeat: the loop must have completed a period (write())
  // within cfg.loop_hang_bound while it runs the drive. Past it the heartbeat stops and fault_hold
  // quick-stops the drive; when the loop comes back the cause says how long it was gone.
  void check_loop(Clock::time_point now) {
    if (cfg.loop_hang_bound.count() <= 0) return;
    const Clock::rep count = loop_write_count.load(std::memory_order_acquire);
    if (count == 0) return;
    const Clock::time_point last{Clock::duration(count)};
    const std::string allows = " (the bench allows " + std::to_string(cfg.loop_hang_bound.count()) + " ms)";
    if (!loop_hung) {
      if (now - last <= cfg.loop_hang_bound) return;
      loop_hung = true;
      loop_last_write = last;
      error(who + ": control loop hung: no period completed for " + std::to_string(ms_of(now - last)) + " ms" + allows +
            "; the bench stopped its heartbeat and quick-stopped the drive");
      publish();
    } else if (!loop_hang_measured && last > loop_last_write) {
      loop_hang_measured = true;
      error(who + ": control loop hung for " + std::to_string(ms_of(last - loop_last_write)) + " ms" + allows +
            "; the bench stopped its heartbeat and quick-stopped the drive");
      h.fault_cause = h.last_error;  // the same cause, now with its length
      publish();
    }
  }

  // -- switching off (cia402_drive_off.cpp) --
  // Blocking, never on the I/O thread: quick stop then disable voltage by SDO (0x6040), the state
  // read back by SDO (0x6041) and published; where SDO fails, NMT stop. Records it in `off`.
  void switch_off_by_sdo(const std::string& asked_by, Clock::time_point asked);
  // I/O thread: runs switch_off_by_sdo on off_thread (once at a time).
  void start_switch_off(const char* why);
  // Setup threads: waits for a switch-off the I/O thread started to end (before the next setup
  // call uses the SDO channel, or the client goes).
  void end_switch_off();

  void run_on_io(std::function<void()> fn) {
    std::promise<void> done;
    auto fut = done.get_future();
    asio::post(io, [&] {
      fn();
      done.set_value();
    });
    fut.wait();
  }
};

}  // namespace hil::drv
