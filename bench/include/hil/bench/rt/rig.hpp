// A rig: what the real-time loop reads the valve and the chamber from, and writes the motor
// command to. One lifecycle for every rig (ros2_control's SystemInterface):
//
//   configure(setup)   blocking, throws: open devices, check identities, map PDOs/registers,
//                      (simulated rig: build and settle the plant for this run)
//   activate()         blocking, throws: enable the drive; after it read()/write() may run
//   read(now, period)  real-time safe: the newest reading, from memory (mailboxes), never waiting
//   write(now, period) real-time safe: hand the command over, never waiting
//   deactivate()       blocking, never throws: disable the drive; safe to call twice
//
// The runner goes through the whole lifecycle once per run (a fresh plant, a fresh enable).
// configure/activate/deactivate run on the campaign runner's thread; read/write/health run on
// the loop thread. A hardware rig keeps its own I/O thread and exchanges data with the loop
// through lock-free mailboxes (drivers/include/hil/drv/io_types.hpp), so read/write only copy.
// Rigs hold no timing code: TimedRig (below) measures every call.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <string_view>

#include "hil/bench/rt/loop_stats.hpp"
#include "hil/drv/io_types.hpp"

namespace hil::bench {

struct LoopProgramme;

using Clock = std::chrono::steady_clock;  // CLOCK_MONOTONIC on Linux
inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// What the loop reads each period, SI. NaN marks what this rig does not have.
struct RigReading {
  double p_meas_pa = kNaN;         // pressure transducer
  double theta_motor_rad = kNaN;   // drive encoder (load side)
  double theta_target_rad = kNaN;  // the target the drive holds now (used once, to start without a jump)
  // Truth only a simulated rig knows (recorded, never given to the controller).
  double theta_valve_rad = kNaN;
  double p_chamber_pa = kNaN;
};

// What the loop writes each period.
struct RigCommand {
  double theta_cmd_rad = 0;
  bool enable = true;
  double gap_rad = kNaN;  // rigs with programmable_gap(): the true backlash over this period
                          // (campaign programme or operator override); NaN for the others
};

enum class RigStatus : std::uint8_t {
  ok,     // fresh data (read) / command handed over (write)
  stale,  // no fresh data: the newest is older than the rig's own freshness limit (a CAN rig:
          // no TPDO since the last SYNC; a Modbus rig polling every 2 ms: a value older than two
          // polls). Counts toward the watchdog; the controller holds its command.
  fault,  // the device or its link reports a fault; health().last_error says which
};

// Link and device health as the bench reports it (a summary of drv::DeviceHealth).
struct RigHealth {
  bool connected = false;
  bool fault = false;
  std::uint64_t reads = 0, stale_reads = 0, fault_reads = 0;
  std::uint64_t reconnects = 0;  // links the clients reopened (Modbus reconnects, CAN bus-off recoveries)
  // The same by device: a bus-off recovery of the drive and a Modbus timeout of the transducer
  // are different stories, and a record that only sums them cannot tell which one happened.
  std::uint64_t drive_reconnects = 0, transducer_reconnects = 0;
  std::array<char, 256> last_error{};  // NUL-terminated

  std::string_view last_error_text() const noexcept { return last_error.data(); }
  void set_last_error(std::string_view text) noexcept {
    const std::size_t n = text.size() < last_error.size() - 1 ? text.size() : last_error.size() - 1;
    std::memcpy(last_error.data(), text.data(), n);
    last_error[n] = '\0';
  }
};

// What a run tells its rig at configure.
struct RigSetup {
  const LoopProgramme* programme = nullptr;  // plant, seed, schedules (simulated rigs)
  double period_s = 1e-3;                    // the control period dT (loop time, not wall time)
  double p_initial_pa = kNaN;                // the reference at t = 0 (a simulated rig settles there)
  double gap_initial_rad = kNaN;             // the programmed gap at t = 0
};

// Faults a rig can fake on purpose (simulated rigs; hardware rigs refuse them).
enum class RigFault : std::uint8_t {
  silent,  // stop answering: reads are stale, commands are not received
};

class Rig {
 public:
  Rig() = default;
  virtual ~Rig() = default;
  Rig(const Rig&) = delete;
  Rig& operator=(const Rig&) = delete;

  virtual std::string_view kind() const noexcept = 0;  // "sim", "can", "modbus", "hybrid"
  // What a rig can do, each on its own (a hybrid rig has real hardware, so it runs in real time,
  // but a simulated valve, so it takes a programmed gap and knows the truth):
  // no hardware in the loop: any speed, faults faked on purpose (RigFault).
  virtual bool simulated() const noexcept { return false; }
  // RigCommand::gap_rad sets the true backlash (campaign programme, operator gap changes).
  virtual bool programmable_gap() const noexcept { return false; }
  // RigReading has the valve angle and the chamber pressure (the telemetry's truth columns).
  virtual bool knows_truth() const noexcept { return false; }

  // Setup; may block and throw messages that name the device, key or register.
  virtual void configure(const RigSetup& setup) = 0;
  virtual void activate() = 0;
  virtual void deactivate() noexcept = 0;
  // Any thread: configure() and activate(), in progress or to come, throw instead of waiting out
  // their timeouts (a drive's are up to 600 s each): an operator's abort of a run being set up.
  // For good: the rig is being given up. A rig whose setup does not wait may leave it a no-op.
  virtual void cancel_setup() noexcept {}
  // Why the last deactivate() could not switch the drive off (it may still be enabled); empty
  // when it did, or when there is nothing to switch off.
  virtual std::string deactivate_failure() const { return {}; }
  // How the drive was last switched off (the path, what asked, how long, the state read back):
  // the run's record. Empty path for a rig with no drive to switch off.
  virtual drv::SwitchOff switch_off() const { return {}; }

  // Real-time safe: noexcept, no allocation, no lock, no I/O, no waiting.
  virtual RigStatus read(Clock::time_point now, Clock::duration period, RigReading& out) noexcept = 0;
  virtual RigStatus write(Clock::time_point now, Clock::duration period, const RigCommand& command) noexcept = 0;
  virtual RigHealth health() const noexcept = 0;
  // Real-time safe: the last write's target went out to the drive (a CAN rig: a SYNC carried it).
  // False when a newer write would replace it unsent; the loop then shapes the next target from
  // the last one sent (target_shaper.hpp). Rigs that send every write: always true.
  virtual bool target_sent() const noexcept { return true; }
  // Real-time safe. Returns false when this rig cannot fake that fault.
  virtual bool inject(RigFault /*fault*/, bool /*on*/) noexcept { return false; }
};

// The non-virtual wrapper the loop calls: it measures every read and write, so rigs hold no
// timing code. `now` is the clock that measures (tests pass a fake); nullptr: simulated time,
// where a call takes no time, and nothing is measured. Real-time safe.
class TimedRig {
 public:
  using NowFn = Clock::time_point (*)() noexcept;
  explicit TimedRig(Rig& rig, NowFn now = &Clock::now) noexcept : rig_(rig), now_(now) {}
  TimedRig(const TimedRig&) = delete;
  TimedRig& operator=(const TimedRig&) = delete;

  RigStatus read(Clock::time_point now, Clock::duration period, RigReading& out) noexcept {
    if (now_ == nullptr) return rig_.read(now, period, out);
    const auto t0 = now_();
    const RigStatus s = rig_.read(now, period, out);
    read_time_.add(now_() - t0);
    return s;
  }
  RigStatus write(Clock::time_point now, Clock::duration period, const RigCommand& command) noexcept {
    if (now_ == nullptr) return rig_.write(now, period, command);
    const auto t0 = now_();
    const RigStatus s = rig_.write(now, period, command);
    write_time_.add(now_() - t0);
    return s;
  }
  Rig& rig() noexcept { return rig_; }
  const LatencyHistogram& read_time() const noexcept { return read_time_; }
  const LatencyHistogram& write_time() const noexcept { return write_time_; }

 private:
  Rig& rig_;
  NowFn now_;
  LatencyHistogram read_time_, write_time_;
};

}  // namespace hil::bench
