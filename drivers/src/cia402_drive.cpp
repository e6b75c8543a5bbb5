#include "hil/drv/cia402_drive.hpp"

#include <sys/eventfd.h>
#include <unistd.h>

#include <atomic>
#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/posix/stream_descriptor.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <deque>
#include <future>
#include <thread>

#include "hil/drv/socketcan.hpp"
#include "setup_util.hpp"

namespace hil::drv {

namespace asio = boost::asio;
using namespace canopen;
using std::chrono::milliseconds;

namespace {
// CiA 301: "client/server command specifier not valid or unknown", how the client refuses a
// segmented transfer it does not implement.
constexpr std::uint32_t kSdoAbortCommandSpecifier = 0x05040001;
constexpr std::uint32_t kSdoAbortTimedOut = 0x05040000;  // "SDO protocol timed out"
}  // namespace

// ---- the client ------------------------------------------------------------------------------

struct Cia402Drive::Impl {
  struct SdoRequest {
    bool upload = false;
    std::uint16_t index = 0;
    std::uint8_t sub = 0;
    std::uint32_t value = 0;
    std::uint8_t size = 0;
    int tries = 0;
    // Replies that did not answer this request (another object, the wrong service): a drive
    // that answers wrongly is not a silent one, and the timeout message says so.
    int ignored = 0;
    std::string last_ignored;
    std::promise<std::uint32_t> done;
  };

  Cia402Config cfg;
  std::string who;  // "CiA 402 drive node 5 on vcan0"
  std::uint8_t n;
  asio::io_context io;
  asio::executor_work_guard<asio::io_context::executor_type> work{io.get_executor()};
  std::unique_ptr<CanTransport> tr;
  asio::steady_timer sync_timer{io}, hb_timer{io}, sdo_timer{io}, bus_timer{io}, bench_hb_timer{io}, guard_timer{io};
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
  std::deque<std::shared_ptr<SdoRequest>> sdo_queue;
  std::shared_ptr<SdoRequest> sdo_active;

  explicit Impl(Cia402Config c) : cfg(std::move(c)), n(cfg.node_id) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "CiA 402 drive node %u on %s", n, cfg.interface.c_str());
    who = buf;
    h.heartbeat_timeout = cfg.heartbeat_timeout;
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
    const bool client_fault = h.heartbeat_lost || rebooted || left_operational || position_jump;
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
    // the client still holds the drive in quick stop, and the rig must see why (it used to see a
    // drive that "switched itself off" with no fault).
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
        on_sdo(f);
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
      error(who + ": the drive left NMT operational (heartbeat says " + std::string(to_string(static_cast<NmtState>(s))) + ", " +
            state + "); it no longer processes PDOs; configure() again");
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

  // -- SDO client --
  void on_sdo(const CanFrame& f) {
    const auto r = parse_sdo_reply(f);
    if (r.kind == SdoReply::Kind::malformed) return malformed(f, "SDO reply");
    if (!sdo_active) return;  // stray reply, e.g. late for a request that already timed out
    auto req = sdo_active;
    const auto ignore = [&] {
      ++req->ignored;
      req->last_ignored = to_string(f);
    };
    if (r.index != req->index || r.sub != req->sub) return ignore();
    const std::string obj = object_name(req->index, req->sub);
    const std::string op = req->upload ? "SDO read " + obj : "SDO write " + obj;
    switch (r.kind) {
      case SdoReply::Kind::upload:
        if (!req->upload) return ignore();
        return sdo_finish(nullptr, r.value);
      case SdoReply::Kind::download:
        if (req->upload) return ignore();
        return sdo_finish(nullptr, 0);
      case SdoReply::Kind::abort: {
        ++h.aborts_or_exceptions;
        char code[16];
        std::snprintf(code, sizeof code, "0x%08X", r.value);
        const std::string text = who + ": " + op + ": abort " + code + " (" + std::string(sdo_abort_name(r.value)) + ")";
        error(text);
        return sdo_finish(std::make_exception_ptr(SdoAbortError(text, req->index, req->sub, r.value)), 0);
      }
      default: {
        const std::string text = who + ": " + op + ": the drive started a segmented transfer; only expedited SDO is supported";
        error(text);
        // Tell the drive, or its SDO server stays in the transfer waiting for our segment requests.
        send(sdo_abort(n, req->index, req->sub, kSdoAbortCommandSpecifier, false));
        return sdo_finish(std::make_exception_ptr(DriveError(text)), 0);
      }
    }
  }

  void sdo_finish(std::exception_ptr err, std::uint32_t value) {
    publish();  // counters first: the caller may look at health() as soon as it wakes
    sdo_timer.cancel();
    auto req = std::move(sdo_active);
    sdo_active.reset();
    if (err)
      req->done.set_exception(err);
    else
      req->done.set_value(value);
    sdo_next();
  }

  void sdo_next() {
    if (sdo_active || sdo_queue.empty()) return;
    sdo_active = sdo_queue.front();
    sdo_queue.pop_front();
    sdo_send();
  }

  void sdo_send() {
    auto& r = *sdo_active;
    ++r.tries;
    send(r.upload ? sdo_upload(n, r.index, r.sub) : sdo_download(n, r.index, r.sub, r.value, r.size));
    sdo_timer.expires_after(cfg.sdo_timeout);
    sdo_timer.async_wait([this, req = sdo_active](const boost::system::error_code& ec) {
      if (ec || sdo_active != req) return;
      ++h.timeouts;
      if (req->tries <= cfg.sdo_retries) {
        sdo_send();
        return;
      }
      const std::string text =
          who + ": SDO " + (req->upload ? "read " : "write ") + object_name(req->index, req->sub) +
          (req->ignored == 0 ? ": no reply after " : ": no matching reply after ") + std::to_string(req->tries) + " tries of " +
          std::to_string(cfg.sdo_timeout.count()) + " ms" +
          (req->ignored == 0 ? std::string()
                             : " (" + std::to_string(req->ignored) +
                                   " replies ignored: another object or the wrong service; last " + req->last_ignored + ")");
      error(text);
      // CiA 301: the client aborts a transfer it gave up on, so a drive that was merely slow
      // drops it rather than answering it into the next request.
      send(sdo_abort(n, req->index, req->sub, kSdoAbortTimedOut, false));
      publish();
      sdo_finish(std::make_exception_ptr(DriveError(text)), 0);
    });
  }

  std::uint32_t sdo(bool upload, std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size) {
    if (std::this_thread::get_id() == thread.get_id()) throw DriveError(who + ": SDO called from the I/O thread");
    auto req = std::make_shared<SdoRequest>();
    req->upload = upload, req->index = index, req->sub = sub, req->value = value, req->size = size;
    auto fut = req->done.get_future();
    asio::post(io, [this, req] {
      sdo_queue.push_back(req);
      sdo_next();
    });
    const auto budget = (cfg.sdo_timeout + milliseconds(50)) * (cfg.sdo_retries + 1) * 4 + std::chrono::seconds(2);
    // In slices, so that a cancelled setup call does not wait out the request's tries. The
    // request stays with the I/O thread, which ends it by its own timeout.
    const auto until = Clock::now() + budget;
    while (fut.wait_for(milliseconds(2)) != std::future_status::ready) {
      throw_if_cancelled();
      if (Clock::now() > until) throw DriveError(who + ": SDO " + object_name(index, sub) + ": the I/O thread did not answer");
    }
    return fut.get();
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
    // A request is used now or dropped: one made while the drive was healthy used to stay armed
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
      // While bus-off nothing goes out (as SYNC and RPDO); the drive's consumer then acts as on a dead bench.
      if (!bus_off_latched) send(canopen::heartbeat(cfg.bench_heartbeat.node_id, NmtState::operational));
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
      if (!bus_off_latched) {
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
    hb_timer.async_wait([this](const boost::system::error_code& ec) {
      if (ec) return;
      if (expect_heartbeat && !h.heartbeat_lost && Clock::now() - h.last_heartbeat > cfg.heartbeat_timeout) {
        h.heartbeat_lost = true;
        error(who + ": heartbeat lost (none for " + std::to_string(cfg.heartbeat_timeout.count()) + " ms)");
        publish();
      }
      arm_hb_timer();
    });
  }

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

Cia402Drive::Cia402Drive(Cia402Config config, CanTransportFactory transport) : impl_(std::make_unique<Impl>(std::move(config))) {
  auto& m = *impl_;
  // A period the bus cannot carry would only show as stale feedback every period (or, before,
  // a period bent into 100 us..100 ms by the rig): refused here, before anything is opened.
  if (m.cfg.sync_period < m.cfg.min_sync_period()) {
    throw DriveError(m.who + ": a SYNC period of " + std::to_string(m.cfg.sync_period.count()) + " us is shorter than the " +
                     std::to_string(m.cfg.min_sync_period().count()) + " us RPDO1 + SYNC + TPDO1 take at " +
                     std::to_string(m.cfg.bitrate) + " bit/s");
  }
  if (!transport) transport = SocketCanTransport::factory(m.cfg.interface);
  const std::uint32_t n = m.n;
  m.tr = transport(m.io, {{kHeartbeat + n, 0x7FF}, {kTpdo1 + n, 0x7FF}, {kSdoTx + n, 0x7FF}, {kEmcy + n, 0x7FF}});
  m.tr->start([&m](const CanFrame& f) { m.on_frame(f); });
  if (m.cfg.sync_source == Cia402Config::SyncSource::loop) {
    m.kick_fd = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    if (m.kick_fd < 0) throw DriveError(m.who + ": eventfd failed");
    m.kick.assign(m.kick_fd);
    m.arm_kick();
  }
  m.sync_timer.expires_after(m.cfg.sync_period);
  m.arm_sync_timer();
  m.arm_hb_timer();
  m.publish();
  m.thread = std::thread([&m] { m.io.run(); });
}

Cia402Drive::~Cia402Drive() {
  auto& m = *impl_;
  asio::post(m.io, [&m] {
    m.tr->stop();
    m.sync_timer.cancel(), m.hb_timer.cancel(), m.sdo_timer.cancel(), m.bus_timer.cancel(), m.bench_hb_timer.cancel(),
        m.guard_timer.cancel();
    boost::system::error_code ec;
    m.kick.close(ec);
  });
  m.work.reset();
  m.io.stop();
  if (m.thread.joinable()) m.thread.join();
}

void Cia402Drive::configure() {
  auto& m = *impl_;
  const Impl::SetupCall call(m, "configure()");
  const auto n = m.n;
  m.run_on_io([&m] {
    m.pdo_running = false;
    m.expect_heartbeat = false;
    m.rebooted = false;
    m.seen_operational = false;
    m.left_operational = false;
    m.position_jump = false;
    m.position_read_valid = false;
    m.reset_pending = false;
    m.fault_hold = false;
    m.fb.valid = false;
    m.target = static_cast<std::uint8_t>(cia402::Target::disabled);
    m.publish();
  });
  const auto boots = m.bootups.load();
  m.notes.clear();
  nmt(NmtCommand::reset_communication);
  if (!m.wait_for(m.cfg.boot_timeout, [&] { return m.bootups.load() > boots; })) {
    char id[8];
    std::snprintf(id, sizeof id, "0x%03X", kHeartbeat + n);
    throw DriveError(m.who + ": no boot-up message (" + id + ") within " + std::to_string(m.cfg.boot_timeout.count()) +
                     " ms of NMT reset communication");
  }
  const std::uint32_t device_type = sdo_read(0x1000, 0);
  // A boot-up from here on means the drive reset while we set it up: its PDO mapping, 0x1017 and
  // mode are back at their defaults, so what configure() wrote is gone (it used to carry on and
  // fail later, or run on the drive's default mapping). Counted from the first SDO reply, not from
  // the reset's boot-up: a drive just powered on sends its own boot-up too, and on a real bus
  // (vcan) that one can be the boot-up waited for above, the reset's coming just after. The bus
  // keeps a node's frames in order, so both come before the reply to a request sent after them.
  const auto booted = m.bootups.load();
  const auto no_reboot = [&](const char* when) {
    if (m.bootups.load() != booted) {
      throw DriveError(m.who + ": the drive rebooted during configure() (boot-up message " + when +
                       "); what was written is lost; configure() again");
    }
  };
  if ((device_type & 0xFFFF) != 402) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "0x%08X", device_type);
    throw DriveError(m.who + ": not a CiA 402 device (0x1000:00 device type = " + buf + ")");
  }
  bool guarding = false;
  try {
    sdo_write(0x1017, 0, static_cast<std::uint32_t>(m.cfg.heartbeat_producer.count()), 2);
  } catch (const SdoAbortError& e) {
    if (e.code != 0x06020000u && e.code != 0x06090011u) throw;
    guarding = configure_node_guarding();  // CiA 301: node guarding in place of the heartbeat
  }
  configure_bench_watch(guarding);
  // PDO mapping, CiA 301 7.5.2.36: invalidate, clear count, map, set count, set type, validate.
  const std::uint32_t rpdo = kRpdo1 + n, tpdo = kTpdo1 + n;
  sdo_write(0x1400, 1, kCobIdInvalid | rpdo, 4);
  sdo_write(0x1600, 0, 0, 1);
  sdo_write(0x1600, 1, 0x60400010, 4);  // controlword, 16 bit
  sdo_write(0x1600, 2, 0x607A0020, 4);  // target position, 32 bit
  sdo_write(0x1600, 0, 2, 1);
  sdo_write(0x1400, 2, 1, 1);  // synchronous: applied at the next SYNC
  sdo_write(0x1400, 1, rpdo, 4);
  sdo_write(0x1800, 1, kCobIdInvalid | tpdo, 4);
  sdo_write(0x1A00, 0, 0, 1);
  sdo_write(0x1A00, 1, 0x60410010, 4);  // statusword
  sdo_write(0x1A00, 2, 0x60640020, 4);  // position actual value
  sdo_write(0x1A00, 0, 2, 1);
  sdo_write(0x1800, 2, 1, 1);  // sent on every SYNC
  sdo_write(0x1800, 1, tpdo, 4);
  // Optional objects: a drive may lack them (CiA 301 needs no more than one PDO each way;
  // 0x60C2 and the limits are optional in CiA 402). Absent means nothing to write.
  const auto optional_write = [&](std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size,
                                  const std::string& what) {
    try {
      sdo_write(index, sub, value, size);
      return true;
    } catch (const SdoAbortError& e) {
      if (e.code != 0x06020000u && e.code != 0x06090011u) throw;
      const std::string note = object_name(index, sub) + " absent: " + what;
      m.notes.push_back(note);
      m.run_on_io([&m, note] {
        m.error(m.who + ": " + note);
        m.publish();
      });
      return false;
    }
  };
  if (m.cfg.disable_unused_pdos) {
    // CiA 301: a PDO is made invalid by setting bit 31 of its own COB-ID (a drive may use other
    // ids than the predefined connection set, and bits 29/30 say more than the id): read, then
    // written back with bit 31. It used to write the predefined id with bit 31.
    const auto invalidate = [&](std::uint16_t comm, const std::string& name) {
      std::uint32_t cob = 0;
      try {
        cob = sdo_read(comm, 1);
      } catch (const SdoAbortError& e) {
        if (e.code != 0x06020000u && e.code != 0x06090011u) throw;
        const std::string note = object_name(comm, 1) + " absent: " + name + " does not exist, nothing to disable";
        m.notes.push_back(note);
        m.run_on_io([&m, note] {
          m.error(m.who + ": " + note);
          m.publish();
        });
        return;
      }
      if (!(cob & kCobIdInvalid)) sdo_write(comm, 1, cob | kCobIdInvalid, 4);
    };
    for (std::uint32_t k = 1; k <= 3; ++k) {
      invalidate(static_cast<std::uint16_t>(0x1400 + k), "RPDO" + std::to_string(k + 1));
      invalidate(static_cast<std::uint16_t>(0x1800 + k), "TPDO" + std::to_string(k + 1));
    }
  }
  // 0x1006 communication cycle period (CiA 301, us): the SYNC period, so that a drive that
  // watches its SYNC consumer knows the period (optional: a drive may not have it).
  optional_write(0x1006, 0, static_cast<std::uint32_t>(m.cfg.sync_period.count()), 4, "the drive does not watch the SYNC period");
  sdo_write(cia402::kModesOfOperation, 0, static_cast<std::uint8_t>(cia402::kModeCsp), 1);
  // The mode display may follow the request some time later: poll it until transition_ms.
  std::int8_t mode = 0;
  const auto mode_until = Clock::now() + m.cfg.transition_timeout;
  for (;;) {
    mode = static_cast<std::int8_t>(sdo_read(cia402::kModesDisplay, 0) & 0xFF);
    if (mode == cia402::kModeCsp || Clock::now() > mode_until) break;
    std::this_thread::sleep_for(milliseconds(1));
  }
  if (mode != cia402::kModeCsp) {
    throw DriveError(m.who + ": did not enter cyclic synchronous position mode within " +
                     std::to_string(m.cfg.transition_timeout.count()) + " ms (0x6061:00 = " + std::to_string(mode) + ")");
  }
  // 0x60C2 is a u8 value times 10^index seconds: the coarsest exact (value, index), else the
  // nearest the u8 can hold, with a note. (It used to be us/100 cast to a byte: 1050 us was sent
  // as 1.0 ms, and 25600 us as 0.)
  const long long us = m.cfg.sync_period.count();
  long long ip_value = 0;
  int ip_index = 0;
  for (const auto& [unit_us, index] :
       {std::pair{1000000LL, 0}, {100000LL, -1}, {10000LL, -2}, {1000LL, -3}, {100LL, -4}, {10LL, -5}, {1LL, -6}}) {
    if (us % unit_us == 0 && us / unit_us <= 255) {
      ip_value = us / unit_us, ip_index = index;
      break;
    }
  }
  if (ip_value == 0) {  // not exact in any unit: round in the finest unit whose value fits a byte
    for (const auto& [unit_us, index] : {std::pair{10LL, -5}, {100LL, -4}, {1000LL, -3}, {10000LL, -2}, {100000LL, -1}}) {
      ip_value = (us + unit_us / 2) / unit_us, ip_index = index;
      if (ip_value <= 255) break;
    }
  }
  ip_value = std::min(ip_value, 255LL);  // over 25.5 s: the longest the byte holds, with the note
  if (optional_write(cia402::kInterpolationPeriod, 1, static_cast<std::uint32_t>(ip_value), 1,
                     "the drive takes its interpolation period from SYNC")) {
    sdo_write(cia402::kInterpolationPeriod, 2, static_cast<std::uint8_t>(ip_index), 1);
    long long written_us = ip_value;
    for (int k = -6; k < ip_index; ++k) written_us *= 10;
    if (written_us != us) {
      const std::string note = "0x60C2 interpolation period " + std::to_string(ip_value) + " x 10^" + std::to_string(ip_index) +
                               " s is the nearest to the SYNC period of " + std::to_string(us) + " us a byte can hold";
      m.notes.push_back(note);
      m.run_on_io([&m, note] {
        m.error(m.who + ": " + note);
        m.publish();
      });
    }
  }
  const auto& lim = m.cfg.limits;
  const double rpc = std::abs(m.cfg.units.rad_per_count());
  const auto counts = [rpc](double x) { return static_cast<std::uint32_t>(std::min(std::nearbyint(x / rpc), 4294967294.0)); };
  // The window in effect: the file's, or the drive's own (0xFFFFFFFF: monitoring off).
  double window_rad = 0;
  if (lim.following_error_window_rad > 0) {
    if (optional_write(cia402::kFollowingErrorWindow, 0, counts(lim.following_error_window_rad), 4,
                       "no following error window to set")) {
      window_rad = counts(lim.following_error_window_rad) * rpc;
    }
  } else if (m.cfg.target_velocity_rad_s > 0) {
    try {
      const std::uint32_t w = sdo_read(cia402::kFollowingErrorWindow, 0);
      if (w != 0xFFFFFFFFu) window_rad = w * rpc;
    } catch (const SdoAbortError& e) {
      if (e.code != 0x06020000u && e.code != 0x06090011u) throw;
    }
  }
  if (const std::string problem = following_window_problem(m.cfg, window_rad); !problem.empty()) {
    throw DriveError(m.who + ": " + problem);
  }
  if (lim.following_error_timeout.count() >= 0) {
    optional_write(cia402::kFollowingErrorTimeout, 0, static_cast<std::uint32_t>(lim.following_error_timeout.count()), 2,
                   "no following error timeout to set");
  }
  if (lim.max_profile_velocity_rad_s > 0) {
    optional_write(cia402::kMaxProfileVelocity, 0, counts(lim.max_profile_velocity_rad_s), 4, "no max profile velocity to set");
  }
  if (lim.quick_stop_deceleration_rad_s2 > 0) {
    optional_write(cia402::kQuickStopDeceleration, 0, counts(lim.quick_stop_deceleration_rad_s2), 4,
                   "no quick stop deceleration to set");
  }
  const auto read_time = Clock::now();
  const auto pos = static_cast<std::int32_t>(sdo_read(cia402::kPositionActual, 0));
  no_reboot("while the objects were written");
  m.command.store({{m.cfg.units.to_rad(pos), false, false}, m.writes.load()});
  m.run_on_io([&m, pos, read_time] {
    m.last_pos_counts = pos;
    m.position_read_valid = true;
    m.position_read_time = read_time;
    m.fb.valid = false;  // a TPDO before NMT start (none is due) neither counts as flowing nor sets the position
    m.fb.position_rad = m.cfg.units.to_rad(pos);
    m.h.last_heartbeat = Clock::now();
    m.expect_heartbeat = true;
    m.pdo_running = true;
    m.publish();
  });
  nmt(NmtCommand::start);
  const bool up = m.wait_for(m.cfg.boot_timeout, [&] {
    return (m.nmt_now.load() == static_cast<std::uint8_t>(NmtState::operational) && m.feedback.load().valid) ||
           m.bootups.load() != booted;
  });
  no_reboot("after NMT start");
  if (!up) {
    throw DriveError(m.who + ": not operational with TPDOs flowing within " + std::to_string(m.cfg.boot_timeout.count()) +
                     " ms of NMT start (last heartbeat state " + std::string(to_string(static_cast<NmtState>(m.nmt_now.load()))) +
                     ")");
  }
  bool jumped = false;
  m.run_on_io([&m, &jumped] { jumped = m.position_jump; });
  if (jumped) {
    throw DriveError(m.who + ": the first TPDO's 0x6064 is not the position read by SDO just before (" +
                     std::string(health().last_error_text()) + ")");
  }
}

// The drive watches the bench: the bench's heartbeat runs from here on, the drive's consumer
// heartbeat time 0x1016 gets an entry for it and 0x6007 says what the drive does when it stops.
// A drive without a producer heartbeat time: node guarding (0x100C guard time, 0x100D life time
// factor), the client's requests every guard time, the replies watched as the heartbeat.
bool Cia402Drive::configure_node_guarding() {
  auto& m = *impl_;
  const auto& g = m.cfg.node_guarding;
  try {
    sdo_write(0x100C, 0, static_cast<std::uint32_t>(g.guard_time.count()), 2);
    sdo_write(0x100D, 0, static_cast<std::uint32_t>(g.life_time_factor), 1);
  } catch (const SdoAbortError& e) {
    if (e.code != 0x06020000u && e.code != 0x06090011u) throw;
    throw DriveError(m.who + ": the drive has neither a producer heartbeat time 0x1017 nor node guarding (0x100C/0x100D, " +
                     object_name(e.index, e.sub) + " absent): nothing would tell that it stopped answering");
  }
  const std::string note = "0x1017:00 absent: node guarding instead (guard time " + std::to_string(g.guard_time.count()) +
                           " ms, life time factor " + std::to_string(g.life_time_factor) + ": the drive watches the bench for " +
                           std::to_string(g.guard_time.count() * g.life_time_factor) + " ms)";
  m.notes.push_back(note);
  m.run_on_io([&m, note] {
    m.start_guarding();
    m.error(m.who + ": " + note);
    m.publish();
  });
  return true;
}

void Cia402Drive::configure_bench_watch(bool guarding) {
  auto& m = *impl_;
  const auto& bw = m.cfg.bench_heartbeat;
  if (!guarding) m.run_on_io([&m] { m.start_bench_heartbeat(); });
  const auto lacking = [&](std::uint16_t index, const SdoAbortError& e, const std::string& what) {
    if (e.code != 0x06020000u && e.code != 0x06090011u) throw e;
    const std::string text = object_name(index, 0) + " absent: " + what;
    if (bw.required) {
      throw DriveError(m.who + ": " + text +
                       "; a drive that cannot watch the bench holds its last target, powered, when the "
                       "bench dies (bench_heartbeat.required: false runs it anyway)");
    }
    m.notes.push_back(text);
    m.run_on_io([&m, text] {
      m.error(m.who + ": " + text);
      m.publish();
    });
  };
  const std::uint32_t entry = (std::uint32_t{bw.node_id} << 16) | static_cast<std::uint32_t>(bw.drive_timeout.count());
  std::uint32_t entries = 0;
  try {
    // With node guarding the drive's life guarding watches the bench: no consumer heartbeat.
    if (!guarding) entries = sdo_read(0x1016, 0) & 0xFF;
  } catch (const SdoAbortError& e) {
    lacking(0x1016, e, "the drive has no consumer heartbeat time, it cannot tell that the bench died");
  }
  if (entries > 0) {
    // The entry already naming the bench's node, else a free one (time or node 0), else the first.
    std::uint8_t sub = 0, free_sub = 0;
    std::uint32_t sub_value = 0, free_value = 0, first_value = 0;
    for (std::uint8_t s = 1; s <= entries; ++s) {
      const std::uint32_t v = sdo_read(0x1016, s);
      if (s == 1) first_value = v;
      if (((v >> 16) & 0xFF) == bw.node_id) {
        sub = s, sub_value = v;
        break;
      }
      if (free_sub == 0 && ((v & 0xFFFF) == 0 || ((v >> 16) & 0xFF) == 0)) free_sub = s, free_value = v;
    }
    if (sub == 0) {
      sub = free_sub != 0 ? free_sub : 1;
      sub_value = free_sub != 0 ? free_value : first_value;
    }
    // CiA 301: a monitored entry is changed by setting it to 0 first.
    if ((sub_value & 0xFFFF) != 0 && sub_value != entry) sdo_write(0x1016, sub, 0, 4);
    sdo_write(0x1016, sub, entry, 4);
  }
  try {
    sdo_write(cia402::kAbortConnectionOption, 0, static_cast<std::uint16_t>(bw.on_loss), 2);
  } catch (const SdoAbortError& e) {
    lacking(cia402::kAbortConnectionOption, e,
            "the drive has no abort connection option code; what it does on a lost bench heartbeat is its maker's choice");
  }
}

void Cia402Drive::activate() {
  auto& m = *impl_;
  const Impl::SetupCall call(m, "activate()");
  const auto fb = m.feedback.load();
  if (!fb.valid) throw DriveError(m.who + ": activate() before configure()");
  m.command.store({{fb.position_rad, true, false}, m.writes.load()});
  m.reset_request = true;  // activate() is the explicit request: it acknowledges a latched fault
  m.target = static_cast<std::uint8_t>(cia402::Target::operation_enabled);
  bool enabled = false;
  try {
    enabled = m.wait_for(m.cfg.transition_timeout, [&] { return state() == cia402::State::operation_enabled; });
  } catch (const DriveError&) {
    // Cancelled: the enable sequence must not go on with nobody to run the drive (the rig
    // deactivates only a drive whose activate() returned).
    m.target = static_cast<std::uint8_t>(cia402::Target::disabled);
    throw;
  }
  if (!enabled) {
    m.target = static_cast<std::uint8_t>(cia402::Target::disabled);  // the same after a timeout
    throw DriveError(m.who + ": did not reach operation enabled within " + std::to_string(m.cfg.transition_timeout.count()) +
                     " ms (state: " + std::string(cia402::to_string(state())) +
                     "; last error: " + std::string(health().last_error_text()) + ")");
  }
}

void Cia402Drive::deactivate() {
  auto& m = *impl_;
  m.target = static_cast<std::uint8_t>(cia402::Target::switched_on);
  // Under a latched fault the client holds the drive below switched on: off is off enough.
  const auto off = [&] {
    const auto s = state();
    return s == cia402::State::switched_on ||
           (m.fault_hold && (s == cia402::State::switch_on_disabled || s == cia402::State::fault));
  };
  if (!detail::wait_for(m.cfg.transition_timeout, off)) {
    throw DriveError(m.who + ": did not reach switched on within " + std::to_string(m.cfg.transition_timeout.count()) +
                     " ms (state: " + std::string(cia402::to_string(state())) + ")");
  }
}

void Cia402Drive::quick_stop() {
  auto& m = *impl_;
  m.target = static_cast<std::uint8_t>(cia402::Target::quick_stop);
  if (!detail::wait_for(m.cfg.transition_timeout, [&] { return state() == cia402::State::switch_on_disabled; })) {
    throw DriveError(m.who + ": quick stop did not end in switch on disabled within " +
                     std::to_string(m.cfg.transition_timeout.count()) + " ms (state: " + std::string(cia402::to_string(state())) +
                     ")");
  }
}

std::vector<std::string> Cia402Drive::configure_notes() const { return impl_->notes; }

DriveFeedback Cia402Drive::read(Clock::time_point, Clock::duration) noexcept { return impl_->feedback.load(); }

void Cia402Drive::write(Clock::time_point, Clock::duration, const DriveCommand& command) noexcept {
  const std::uint64_t n = impl_->writes.load(std::memory_order_relaxed) + 1;
  impl_->writes.store(n, std::memory_order_relaxed);
  impl_->command.store({command, n});
  if (impl_->kick_fd >= 0) {
    const std::uint64_t one = 1;
    [[maybe_unused]] auto r = ::write(impl_->kick_fd, &one, sizeof one);  // non-blocking eventfd
  }
}

std::string_view Cia402Drive::missing_reply_text() const noexcept {
  return impl_->tpdo_malformed ? "no usable TPDO since the last SYNC: TPDO1 arrives too short (expected 6 bytes: statusword, "
                                 "position actual)"
                               : "no TPDO since the last SYNC";
}

DeviceHealth Cia402Drive::health() const noexcept { return detail::with_age(impl_->health_box); }

bool Cia402Drive::last_command_sent() const noexcept {
  return impl_->sent_write.load(std::memory_order_acquire) == impl_->writes.load(std::memory_order_relaxed);
}

FeedbackFreshness Cia402Drive::freshness() const noexcept {
  return impl_->cfg.sync_source == Cia402Config::SyncSource::loop ? FeedbackFreshness::reply_to_each_write
                                                                  : FeedbackFreshness::polled;
}

cia402::State Cia402Drive::state() const noexcept { return static_cast<cia402::State>(impl_->state_now.load()); }

std::uint32_t Cia402Drive::sdo_read(std::uint16_t index, std::uint8_t sub) { return impl_->sdo(true, index, sub, 0, 0); }

void Cia402Drive::sdo_write(std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size) {
  if (size < 1 || size > 4) throw DriveError(impl_->who + ": SDO write " + object_name(index, sub) + ": size must be 1..4 bytes");
  impl_->sdo(false, index, sub, value, size);
}

void Cia402Drive::nmt(NmtCommand command) {
  auto& m = *impl_;
  asio::post(m.io, [&m, command] {
    // Our own request to leave operational is no surprise: only an unasked-for change is a fault.
    if (command != NmtCommand::start) m.seen_operational = false;
    m.send(canopen::nmt(command, m.n));
  });
}

void Cia402Drive::reset_fault() { impl_->reset_request = true; }

void Cia402Drive::cancel_setup() noexcept { impl_->setup_cancelled = true; }

void Cia402Drive::clear_bus_off() {
  auto& m = *impl_;
  asio::post(m.io, [&m] {
    if (!m.bus_off_latched) return;
    m.bus.reset();
    m.h.bus_state = BusState::error_active;
    m.resume_after_bus_off("bus-off cleared by the operator (policy report)");
  });
}

const Cia402Config& Cia402Drive::config() const { return impl_->cfg; }

}  // namespace hil::drv
