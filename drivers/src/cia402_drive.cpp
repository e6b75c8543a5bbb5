// The CiA 402 client's setup calls (the configure sequence, activate, deactivate, quick stop) and
// its real-time calls over the mailboxes; the I/O thread's side is cia402_drive_impl.hpp, the SDO
// client sdo_client.cpp, the configuration cia402_config.cpp.
#include "hil/drv/cia402_drive.hpp"

#include "cia402_drive_impl.hpp"
#include "hil/drv/socketcan.hpp"

namespace hil::drv {

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
  m.end_switch_off();  // a switch-off the client started needs the I/O thread until it ends
  asio::post(m.io, [&m] {
    m.tr->stop();
    m.sync_timer.cancel(), m.hb_timer.cancel(), m.sdo->cancel(), m.bus_timer.cancel(), m.bench_hb_timer.cancel(),
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
  m.loop_write_count.store(0, std::memory_order_release);
  m.end_switch_off();  // its NMT stop must not land in the middle of this setup
  {
    const std::lock_guard lock(m.off_mutex);
    m.off = {};
  }
  m.run_on_io([&m] {
    m.loop_hung = false;
    m.loop_hang_measured = false;
    m.drive_lost_bench = false;
    m.bench_hb_gap_max = {};
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
  // mode are back at their defaults, so what configure() wrote is gone (carrying on would fail
  // later, or run on the drive's default mapping). Counted from the first SDO reply, not from
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
    // written back with bit 31, never the predefined id with bit 31.
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
  // nearest the u8 can hold, with a note. (us/100 cast to a byte would send 1050 us as 1.0 ms,
  // and 25600 us as 0.)
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
  m.loop_write_count.store(0, std::memory_order_release);  // watched from the loop's first write()
  {
    const std::lock_guard lock(m.off_mutex);
    m.off = {};
  }
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

void Cia402Drive::quick_stop() {
  auto& m = *impl_;
  m.loop_write_count.store(0, std::memory_order_release);
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
  // The loop completed a period: what the I/O thread's hang watch and the bench's heartbeat go by.
  impl_->loop_write_count.store(Clock::now().time_since_epoch().count(), std::memory_order_release);
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

std::uint32_t Cia402Drive::sdo_read(std::uint16_t index, std::uint8_t sub) { return impl_->sdo->read(index, sub); }

SdoClient& Cia402Drive::sdo() { return *impl_->sdo; }

void Cia402Drive::sdo_write(std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size) {
  if (size < 1 || size > 4) throw DriveError(impl_->who + ": SDO write " + object_name(index, sub) + ": size must be 1..4 bytes");
  impl_->sdo->write(index, sub, value, size);
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
