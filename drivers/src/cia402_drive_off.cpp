// Switching a CiA 402 drive off whatever its NMT state. The cyclic controlword (RPDO1) reaches a
// drive only in NMT operational; SDO works in pre-operational too, so where the PDOs cannot carry
// the controlword (pre-operational, no TPDO) 0x6040 is written by SDO and 0x6041 read back by
// SDO; where SDO fails as well (a stopped node answers nothing but NMT) the node is stopped. The
// state reported is the one read back, never the last TPDO's (which stops with the PDOs).
#include "cia402_drive_impl.hpp"
#include "hil/drv/cia402_drive.hpp"

namespace hil::drv {
namespace {

// The power stage is off: no torque, whatever the drive does next.
bool power_off(cia402::State s) {
  return s == cia402::State::switch_on_disabled || s == cia402::State::fault || s == cia402::State::not_ready_to_switch_on;
}

double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

}  // namespace

void Cia402Drive::Impl::switch_off_by_sdo(const std::string& asked_by, Clock::time_point asked) {
  SwitchOff r{.path = "sdo", .asked_by = asked_by, .after_ms = -1, .state = "unknown", .off = false};
  try {
    // Quick stop first (the drive's own ramp, then switch on disabled); a quick stop option code
    // that holds the drive in quick stop active is ended by disable voltage after half the time.
    const auto half = Clock::now() + cfg.transition_timeout / 2, until = Clock::now() + cfg.transition_timeout;
    std::uint16_t cw = cia402::kCwQuickStop;
    sdo->write(cia402::kControlword, 0, cw, 2);
    for (;;) {
      const auto sw = static_cast<std::uint16_t>(sdo->read(cia402::kStatusword, 0));
      const auto st = cia402::decode_statusword(sw);
      r.state = cia402::to_string(st);
      asio::post(io, [this, sw, st] {  // the state read back replaces the stale TPDO's
        fb.statusword = sw;
        state_now = static_cast<std::uint8_t>(st);
        publish();
      });
      if (power_off(st)) {
        r.off = true;
        break;
      }
      if (Clock::now() > until) break;
      if (cw == cia402::kCwQuickStop && (Clock::now() > half || st != cia402::State::quick_stop_active)) {
        cw = cia402::kCwDisableVoltage;
        sdo->write(cia402::kControlword, 0, cw, 2);
      }
      std::this_thread::sleep_for(milliseconds(2));
    }
  } catch (const DriveError& e) {
    // Refused or unanswered: stop the node. A stopped drive processes neither PDO nor SDO and
    // what its power stage does then is its maker's choice: nothing can be read back.
    asio::post(io, [this] {
      seen_operational = false;  // asked for: not a drive that left operational by itself
      send(canopen::nmt(NmtCommand::stop, n));
    });
    r.path = "nmt_stop";
    r.state = std::string("unknown (") + e.what() + ")";
  }
  r.after_ms = ms_since(asked);
  asio::post(io, [this, r] {
    error(who + ": switched off by " + r.path + " (" + r.asked_by + ") in " + std::to_string(std::lround(r.after_ms)) +
          " ms: " + (r.path == "nmt_stop" ? "NMT stop sent, state unknown" : "state read back " + r.state));
    publish();
  });
  const std::lock_guard lock(off_mutex);
  off = r;
}

void Cia402Drive::Impl::end_switch_off() {
  // Its SDO waits are bounded: at most three transfers' tries, then an NMT stop.
  detail::wait_for(cfg.transition_timeout + cfg.sdo_timeout * (cfg.sdo_retries + 1) * 3, [this] { return !off_busy; });
  std::thread done;
  {
    const std::lock_guard lock(off_mutex);
    done = std::move(off_thread);
  }
  if (done.joinable()) done.join();  // outside the lock: the thread takes it to record what it did
}

void Cia402Drive::Impl::start_switch_off(const char* why) {
  if (off_busy.exchange(true)) return;
  const auto asked = Clock::now();
  const std::lock_guard lock(off_mutex);
  if (off_thread.joinable()) off_thread.join();  // the last one has ended: off_busy was clear
  off_thread = std::thread([this, asked, by = std::string("the client: ") + why] {
    switch_off_by_sdo(by, asked);
    off_busy = false;
  });
}

void Cia402Drive::deactivate() {
  auto& m = *impl_;
  m.loop_write_count.store(0, std::memory_order_release);  // no loop runs the drive from here
  const auto asked = Clock::now();
  // A switch-off the client started itself (the drive left operational) ends first.
  m.end_switch_off();
  {
    const std::lock_guard lock(m.off_mutex);
    if (m.off.off) {  // switched off already, by the path recorded
      m.target = static_cast<std::uint8_t>(cia402::Target::disabled);
      return;
    }
  }
  // The cyclic controlword, while the PDOs run: operational, TPDOs arriving.
  const auto pdo_wait = std::min(m.cfg.transition_timeout,
                                 std::max(milliseconds(200), std::chrono::duration_cast<milliseconds>(50 * m.cfg.sync_period)));
  bool pdo_ok = false;
  m.run_on_io([&m, &pdo_ok, pdo_wait] {
    pdo_ok = m.pdo_running && !m.left_operational && !m.rebooted && !m.bus_off_latched &&
             m.nmt_now.load() == static_cast<std::uint8_t>(NmtState::operational) && m.fb.valid &&
             Clock::now() - m.fb.rx_time < pdo_wait;
  });
  m.target = static_cast<std::uint8_t>(cia402::Target::disabled);
  if (pdo_ok && m.wait_for(pdo_wait, [&] { return power_off(state()) && m.feedback.load().rx_time > asked; })) {
    const std::lock_guard lock(m.off_mutex);
    m.off = {.path = "pdo",
             .asked_by = "deactivate()",
             .after_ms = ms_since(asked),
             .state = std::string(cia402::to_string(state())),
             .off = true};
    return;
  }
  m.switch_off_by_sdo(pdo_ok ? "deactivate(): no TPDO showed the drive off" : "deactivate(): the PDOs do not run", asked);
  const SwitchOff r = last_switch_off();
  if (!r.off) {
    throw DriveError(m.who + ": not switched off: " + r.path + " after " + std::to_string(std::lround(r.after_ms)) +
                     " ms, state read back " + r.state);
  }
}

SwitchOff Cia402Drive::last_switch_off() const {
  const std::lock_guard lock(impl_->off_mutex);
  return impl_->off;
}

}  // namespace hil::drv
