#include "hil/bench/rt/device_rig.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <thread>

#include <spdlog/spdlog.h>

#include "hil/bench/rt/loop_input.hpp"
#include "hil/bench/rt/rt_thread.hpp"
#include "hil/drv/canopen.hpp"

namespace hil::bench {

namespace {
double ms(Clock::duration d) noexcept { return std::chrono::duration<double, std::milli>(d).count(); }
}  // namespace

DeviceRig::DeviceRig(const RigConfig& config, const RigKindInfo& kind, Parts parts)
    : config_(config), kind_(kind.kind), capabilities_(kind.capabilities), parts_(std::move(parts)) {
  if (!parts_.drive) throw std::invalid_argument(config_.file.string() + ": rig '" + config_.name + "' has no drive");
  // The capabilities are declared by the kind and delivered by the parts: they must agree, or the
  // runner would offer gap changes the rig ignores (or drop truth columns it has).
  const bool sim_chamber = simulated_chamber();
  if (capabilities_.simulated || capabilities_.programmable_gap != sim_chamber || capabilities_.knows_truth != sim_chamber) {
    throw std::logic_error(kind_ +
                           " rig: its declared capabilities do not match its parts (a real drive is never simulated; "
                           "a programmable gap and the truth come with the simulated chamber, and only with it)");
  }
}

DeviceRig::~DeviceRig() = default;

void DeviceRig::configure(const RigSetup& setup) {
  if (!(setup.period_s > 0)) throw std::invalid_argument(kind_ + " rig: the period must be > 0");
  active_ = false;
  configured_ = false;
  {
    std::lock_guard lock(cancel_mutex_);
    drive_.reset();
  }
  sensor_.reset();
  period_s_ = setup.period_s;
  {
    // The parts' I/O threads answer the loop every period: they inherit this priority (and the
    // runner thread's affinity, which keeps off the loop's CPU).
    const ScopedRealtime io_sched(config_.loop.io_priority);
    if (!io_sched.warning().empty()) spdlog::warn("{} rig '{}': {}", kind_, config_.name, io_sched.warning());
    {
      std::lock_guard lock(cancel_mutex_);
      drive_ = parts_.drive(setup);
      if (setup_cancelled_) drive_->cancel_setup();
    }
    drive_->configure();
    // The transducer's own setup (a connect and a poll, up to its response timeout) takes no
    // cancel: an abort that came during the drive's is not made to wait for it too.
    if (setup_cancelled_) throw std::runtime_error(kind_ + " rig: configure() cancelled before the transducer's setup");
    if (parts_.pressure_sensor) {
      sensor_ = parts_.pressure_sensor(setup);
      sensor_->configure();
    }
  }
  drive_freshness_ = drive_->freshness();
  offset_rad_ = 0;
  if (simulated_chamber()) {
    if (setup.programme == nullptr || !setup.programme->plant) {
      throw std::invalid_argument(kind_ + " rig: configure needs a campaign with a plant");
    }
    const drv::DriveFeedback fb = drive_->read(Clock::now(), Clock::duration::zero());
    if (!fb.valid || !std::isfinite(fb.position_rad))
      throw std::runtime_error(kind_ + " rig: the drive reports no position after configure");
    plant_ = setup.programme->plant;
    state_ = plant_->make_state(setup.programme->seed);
    plant_->settle(state_, setup.p_initial_pa, plant::kNaN, 0.0, setup.gap_initial_rad);
    offset_rad_ = fb.position_rad - state_.s.theta_motor_rad;
    motor_sim_rad_ = state_.s.theta_motor_rad;
    cmd_sim_rad_ = state_.s.theta_cmd_rad;
    gap_rad_ = setup.gap_initial_rad;
    step_pending_ = false;
  }
  last_write_ = {};
  stale_ = Stale::none;
  reads_ = stale_reads_ = fault_reads_ = 0;
  deactivate_error_[0] = '\0';
  implausible_ = Implausible::none;
  enable_held_ = false;
  configured_ = true;
}

void DeviceRig::activate() {
  if (!configured_) throw std::logic_error(kind_ + " rig: activate before configure (or after one that failed)");
  activated_at_ = Clock::now();
  first_write_done_ = false;
  drive_->activate();
  active_ = true;
  // The loop starts from a reading: wait (setup, so it may block) until every device gives a fresh
  // one, however long a loaded machine takes to deliver the first TPDO and poll, up to 5 s.
  const auto until = Clock::now() + std::chrono::seconds(5);
  for (;;) {
    drv::DriveFeedback fb;
    RigStatus s = read_drive(Clock::now(), fb);
    if (s == RigStatus::ok && sensor_) {
      const auto now = Clock::now();
      const drv::PressureReading p = sensor_->read(now, Clock::duration::zero());
      s = p.fault ? RigStatus::fault : (!p.valid || now - p.rx_time > parts_.sensor_max_age) ? RigStatus::stale : RigStatus::ok;
      if (s == RigStatus::stale) {
        stale_ = Stale::transducer;
        stale_age_ms_ = p.valid ? ms(now - p.rx_time) : -1;
      }
    }
    if (s == RigStatus::ok) {
      stale_ = Stale::none;
      enable_held_ = true;  // from here on the drive must stay enabled until a command says otherwise
      return;
    }
    // An operator's abort ends the wait within a poll; the caller's deactivate() turns the drive off.
    if (setup_cancelled_)
      throw std::runtime_error(kind_ + " rig: activate() cancelled while waiting for a fresh reading of every part");
    if (s == RigStatus::fault || Clock::now() > until) {
      const RigHealth h = health();
      throw std::runtime_error(kind_ + " rig: no fresh reading after enabling the drive" +
                               (h.last_error_text().empty() ? std::string() : ": " + std::string(h.last_error_text())));
    }
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
}

void DeviceRig::cancel_setup() noexcept {
  std::lock_guard lock(cancel_mutex_);
  setup_cancelled_ = true;
  if (drive_) drive_->cancel_setup();
}

void DeviceRig::deactivate() noexcept {
  if (!active_ || !drive_) return;
  active_ = false;
  // Always asked, also of a drive that reads as off: its feedback may be stale (a CAN drive out of
  // NMT operational sends no TPDO), and a client that watches the loop stops watching here.
  try {
    drive_->deactivate();
  } catch (const std::exception& e) {
    std::snprintf(deactivate_error_.data(), deactivate_error_.size(), "drive: deactivate: %s", e.what());
  }
}

RigStatus DeviceRig::read_drive(Clock::time_point now, drv::DriveFeedback& fb) noexcept {
  fb = drive_->read(now, Clock::duration::zero());
  if (fb.fault) return RigStatus::fault;
  if (fb.valid && !std::isfinite(fb.position_rad)) {
    implausible_ = Implausible::position_not_finite;
    return RigStatus::fault;
  }
  if (fb.valid && enable_held_ && !fb.enabled) {
    implausible_ = Implausible::disabled;
    implausible_status_ = fb.statusword;
    return RigStatus::fault;
  }
  const bool fresh = drive_freshness_ == drv::FeedbackFreshness::reply_to_each_write
                         ? fb.valid && (last_write_ == Clock::time_point{} || fb.rx_time > last_write_)
                         : fb.valid && (now - fb.rx_time <= parts_.drive_max_age || first_read(fb.rx_time));
  if (fresh) return RigStatus::ok;
  stale_ = Stale::drive;
  stale_age_ms_ = fb.valid ? ms(now - fb.rx_time) : -1;
  return RigStatus::stale;
}

RigStatus DeviceRig::read(Clock::time_point now, Clock::duration period, RigReading& out) noexcept {
  ++reads_;
  if (!active_ || !drive_) {
    ++fault_reads_;
    return RigStatus::fault;
  }
  drv::DriveFeedback fb;
  RigStatus status = read_drive(now, fb);
  if (fb.valid) motor_sim_rad_ = fb.position_rad - offset_rad_;
  out.theta_motor_rad = motor_sim_rad_;
  if (simulated_chamber()) {
    // The physics goes on with the newest encoder angle whether or not it is fresh.
    if (step_pending_) plant_->step(state_, {cmd_sim_rad_, motor_sim_rad_, gap_rad_}, period_s_);
    step_pending_ = false;
    out.p_meas_pa = state_.s.p_meas_pa;
    out.theta_valve_rad = state_.s.theta_valve_rad;
    out.p_chamber_pa = state_.s.p_chamber_pa;
  } else {
    const drv::PressureReading p = sensor_->read(now, period);
    out.p_meas_pa = p.pressure_pa;
    RigStatus ps = RigStatus::ok;
    if (p.fault) {
      ps = RigStatus::fault;
    } else if (!p.valid || (now - p.rx_time > parts_.sensor_max_age && !first_read(p.rx_time))) {
      ps = RigStatus::stale;
      if (status == RigStatus::ok) {
        stale_ = Stale::transducer;
        stale_age_ms_ = p.valid ? ms(now - p.rx_time) : -1;
      }
    }
    status = std::max(status, ps);  // ok < stale < fault
  }
  if (status == RigStatus::ok) stale_ = Stale::none;
  if (status == RigStatus::stale) ++stale_reads_;
  if (status == RigStatus::fault) ++fault_reads_;
  return status;
}

RigStatus DeviceRig::write(Clock::time_point now, Clock::duration period, const RigCommand& command) noexcept {
  if (!active_ || !drive_) return RigStatus::fault;
  if (simulated_chamber()) {
    cmd_sim_rad_ = command.theta_cmd_rad;
    gap_rad_ = command.gap_rad;
    step_pending_ = true;
  }
  first_write_done_ = true;
  if (!command.enable) enable_held_ = false;
  // Taken before the write that asks for the reply: a reply is fresh when it arrived after it.
  if (drive_freshness_ == drv::FeedbackFreshness::reply_to_each_write) last_write_ = Clock::now();
  drive_->write(now, period, {command.theta_cmd_rad + offset_rad_, command.enable, false});
  return RigStatus::ok;
}

bool DeviceRig::target_sent() const noexcept { return !drive_ || drive_->last_command_sent(); }

drv::DriveFeedback DeviceRig::drive_feedback() const noexcept {
  return drive_ ? drive_->read(Clock::now(), Clock::duration::zero()) : drv::DriveFeedback{};
}

RigHealth DeviceRig::health() const noexcept {
  RigHealth h;
  h.reads = reads_;
  h.stale_reads = stale_reads_;
  h.fault_reads = fault_reads_;
  if (!drive_) {
    h.fault = true;
    char text[64];
    std::snprintf(text, sizeof text, "%s rig: not configured", kind_.c_str());
    h.set_last_error(text);
    return h;
  }
  const drv::DeviceHealth d = drive_->health();
  drv::DeviceHealth t;
  if (sensor_) t = sensor_->health();
  h.connected = active_ && d.connected && (!sensor_ || t.connected);
  h.drive_reconnects = d.reconnects;
  h.transducer_reconnects = t.reconnects;
  h.reconnects = d.reconnects + t.reconnects;
  h.fault = !active_ || d.fault || (sensor_ && t.fault) || implausible_ != Implausible::none;
  char text[320];  // room for a drive error of 240 and its prefix; set_last_error keeps what fits
  text[0] = '\0';
  char code[8];
  std::snprintf(code, sizeof code, "0x%04X", d.last_emcy_code);
  // A fault the client holds is told by what latched it (a heartbeat lost, then back, is still
  // the cause of the drive's quick stop), not by whatever came after.
  const char* const drive_error = d.fault && d.fault_cause[0] != '\0' ? d.fault_cause.data() : d.last_error.data();
  if (d.fault && d.last_emcy_code != 0 && std::strstr(drive_error, code) == nullptr) {
    // The newest error is about something else (heartbeat, bus): name the EMCY too.
    std::snprintf(text, sizeof text, "drive: %s (last EMCY 0x%04X)", drive_error, d.last_emcy_code);
  } else if (d.fault) {
    std::snprintf(text, sizeof text, "drive: %s", drive_error);
  } else if (implausible_ == Implausible::position_not_finite) {
    std::snprintf(text, sizeof text, "drive: its position reads as not a number");
  } else if (implausible_ == Implausible::disabled) {
    std::snprintf(text, sizeof text,
                  "drive: switched itself off during the run without reporting a fault (status 0x%04X); every command "
                  "asked it to stay enabled",
                  implausible_status_);
    if (d.last_emcy_code != 0) {  // what the drive said last, in words (0x8130: it lost the bench's heartbeat)
      const std::string_view name = drv::canopen::emcy_class_name(d.last_emcy_code);
      const std::size_t used = std::strlen(text);
      std::snprintf(text + used, sizeof text - used, "; last EMCY 0x%04X (%.*s)", d.last_emcy_code, static_cast<int>(name.size()),
                    name.data());
    }
  } else if (sensor_ && t.fault) {
    std::snprintf(text, sizeof text, "transducer: %s", t.last_error.data());
  } else if (stale_ == Stale::drive && drive_freshness_ == drv::FeedbackFreshness::reply_to_each_write) {
    const std::string_view missing = drive_->missing_reply_text();
    std::snprintf(text, sizeof text, "drive: %.*s (newest %.1f ms old)", static_cast<int>(missing.size()), missing.data(),
                  stale_age_ms_);
  } else if (stale_ == Stale::drive) {
    // Why it is old, when the device said: an exception reply is an answer, not silence.
    std::snprintf(text, sizeof text, "drive: newest feedback %.1f ms old (limit %.1f ms)%s%s", stale_age_ms_,
                  ms(parts_.drive_max_age), d.failing ? ": " : "", d.failing ? d.last_error.data() : "");
  } else if (stale_ == Stale::transducer) {
    std::snprintf(text, sizeof text, "transducer: newest reading %.1f ms old (limit %.1f ms)%s%s", stale_age_ms_,
                  ms(parts_.sensor_max_age), t.failing ? ": " : "", t.failing ? t.last_error.data() : "");
  } else if (deactivate_error_[0] != '\0') {
    std::snprintf(text, sizeof text, "%s", deactivate_error_.data());
  } else if (d.last_error[0] != '\0') {
    std::snprintf(text, sizeof text, "drive: %s", d.last_error.data());
  } else if (sensor_ && t.last_error[0] != '\0') {
    std::snprintf(text, sizeof text, "transducer: %s", t.last_error.data());
  }
  h.set_last_error(text);
  return h;
}

DeviceRig::DriveFactory drive_from_file(const RigConfig& config, drv::CanTransportFactory can_transport) {
  if (!config.devices.drive) throw std::invalid_argument(config.file.string() + ": rig '" + config.name + "' has no drive");
  const int misses = config.safety.watchdog_misses;
  return [recipe = config.devices.drive, misses,
          can_transport = std::move(can_transport)](const RigSetup& setup) -> std::unique_ptr<drv::PositionDrive> {
    return recipe->make({.period_s = setup.period_s, .watchdog_s = misses * setup.period_s, .can_transport = can_transport});
  };
}

DeviceRig::SensorFactory transducer_from_file(const RigConfig& config) {
  if (!config.devices.transducer) {
    throw std::invalid_argument(config.file.string() + ": rig '" + config.name + "' has no pressure transducer");
  }
  return [recipe = config.devices.transducer](const RigSetup& setup) -> std::unique_ptr<drv::PressureSensor> {
    return recipe->make({.period_s = setup.period_s, .can_transport = {}});
  };
}

std::unique_ptr<Rig> make_drive_and_transducer_rig(const RigKindInfo& kind, const RigConfig& config,
                                                   const drv::CanTransportFactory& can_transport) {
  return std::make_unique<DeviceRig>(config, kind,
                                     DeviceRig::Parts{.drive = drive_from_file(config, can_transport),
                                                      .drive_max_age = config.devices.drive->max_age,
                                                      .pressure_sensor = transducer_from_file(config),
                                                      .sensor_max_age = config.devices.transducer->max_age});
}

std::unique_ptr<Rig> make_drive_and_simulated_chamber_rig(const RigKindInfo& kind, const RigConfig& config,
                                                          const drv::CanTransportFactory& can_transport) {
  return std::make_unique<DeviceRig>(config, kind,
                                     DeviceRig::Parts{.drive = drive_from_file(config, can_transport),
                                                      .drive_max_age = config.devices.drive->max_age,
                                                      .pressure_sensor = {},
                                                      .sensor_max_age = {}});
}

}  // namespace hil::bench
