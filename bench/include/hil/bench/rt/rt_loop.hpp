// The real-time loop of one run: every period it reads the rig, steps the controller, applies
// the safety interlocks, writes the rig and pushes a telemetry row, and nothing else. It is the
// one period of every run: on the bench, paced by a clock (rt_thread.hpp), and offline, on the
// simulated rig in simulated time (SimulatedRun below: `hilbench sim`, the tests, the sweeps).
//
// RunLoop is the period's work without the clock: the pacing thread (rt_thread.hpp) wakes it
// on absolute deadlines and passes the times in, so tests drive it with made-up times.
// Operators reach it through a request ring (stop, abort, gap change, faults); it reports through
// the telemetry ring, the event ring and a snapshot mailbox. It never blocks on any of them.
#pragma once

#include <array>
#include <variant>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <vector>

#include "hil/bench/rt/loop_input.hpp"
#include "hil/bench/rt/loop_stats.hpp"
#include "hil/bench/rt/rig.hpp"
#include "hil/bench/rt/safety.hpp"
#include "hil/bench/rt/telemetry_record.hpp"
#include "hil/bench/rt/spsc_ring.hpp"
#include "hil/bench/rt/target_shaper.hpp"
#include "hil/drv/io_types.hpp"
#include "hil/plant/rng.hpp"

namespace hil::cfg {
class Node;
}

namespace hil::bench {

enum class OverrunPolicy : std::uint8_t { count, abort };
// What the loop does when telemetry cannot be recorded: go to the safe state and end the run
// (a run without its record cannot be reviewed), or run on and count the rows not written.
enum class RecordingFaultPolicy : std::uint8_t { safe_state, count };

// The `loop` block of a rig file.
struct LoopConfig {
  int priority = 80;  // SCHED_FIFO priority 1..99; 0 = the normal scheduler
  int cpu = -1;       // pin the loop thread to this CPU; -1 = no pinning
  OverrunPolicy overrun_policy = OverrunPolicy::count;
  int overrun_abort_after = 10;  // policy abort: this many overruns in a row trip the run
  int ring_rows = 65536;         // telemetry ring capacity (rows); the loss counter reports overflow
  int cpu_dma_latency_us = 0;    // PM QoS request while a loop runs; -1 = none
  int io_priority = 0;           // SCHED_FIFO priority of the device clients' I/O threads; 0 = the normal scheduler
  RecordingFaultPolicy recording_fault = RecordingFaultPolicy::safe_state;
  // A real drive's velocity and acceleration limits: the rig is sent targets within them (see
  // target_shaper.hpp). Off (zero) for the simulated rig, whose servo model has its own limits.
  ShapingLimits target_shaping;
  static LoopConfig from_yaml(const cfg::Node& node);
};

// Bits of the loop_flags telemetry column (and of LoopSnapshot::flags).
enum LoopFlag : std::uint32_t {
  kFlagSensorFault = 1u << 0,
  kFlagDriveFault = 1u << 1,
  kFlagRigFault = 1u << 2,     // an injected rig fault (silent) is on
  kFlagGapOverride = 1u << 3,  // the operator set the gap
  kFlagReadMissed = 1u << 4,   // no usable reading this period
  kFlagCmdLimited = 1u << 5,   // an angle or rate limit changed the command
  kFlagSafeState = 1u << 6,
  kFlagOverrun = 1u << 7,      // this period ended after the next deadline
  kFlagDeviceFault = 1u << 8,  // the rig reported a device or link fault (RigStatus::fault)
};

enum class SensorFault : std::uint8_t { none, stuck, dropout, bias, noise };
std::string_view to_string(SensorFault f) noexcept;

// An operator's request, carried from the API to the loop.
struct LoopRequest {
  enum class Kind : std::uint8_t { stop, abort, set_gap, programme_gap, sensor_fault, drive_fault, rig_fault, clear_faults };
  Kind kind = Kind::stop;
  SensorFault sensor = SensorFault::none;
  double value = 0;       // set_gap: gap [rad]; sensor bias: offset [Pa]; sensor noise: RMS [Pa]
  double duration_s = 0;  // faults: 0 = until cleared
  bool on = true;         // drive_fault, rig_fault: on or off
};

// Something the loop did or saw: one struct per kind, each field named with its unit.
namespace event {
struct GapChange {  // the operator set the gap
  double gap_rad;
};
struct GapProgramme {};  // the campaign's gap programme is back
struct SensorFaultSet {  // the operator injected a sensor fault
  SensorFault mode;
  double value_pa;    // bias: offset; noise: RMS; stuck: the pressure held
  double duration_s;  // 0: until cleared
};
struct DriveFaultSet {  // the operator made the drive ignore commands (or stopped that)
  bool on;
  double duration_s;  // 0: until cleared
};
struct RigFaultSet {  // the operator silenced the rig (or stopped that)
  bool on;
  bool accepted;  // the rig can do it
};
struct FaultExpired {  // an injected fault's duration ran out
  SensorFault sensor;  // none: the drive fault
};
struct FaultsCleared {};
struct Tripped {
  Trip reason;
  double value;                    // the reading that tripped it: Pa for pressure, a count for watchdog and overruns
  double limit;                    // in the same unit
  std::array<char, 256> detail{};  // a rig fault or the watchdog: the rig's last error (NUL-terminated)
};
struct SafeState {  // the loop entered the safe state
  double cmd_rad;   // the safe command
};
struct CmdLimited {  // an angle or rate limit changed the command (the start of a streak)
  double requested_rad, sent_rad;
};
struct Overrun {  // a period ended after the next deadline (the start of a streak)
  double late_us;
};
struct Stopped {};  // the operator stopped the run
}  // namespace event

using LoopEventBody = std::variant<event::GapChange, event::GapProgramme, event::SensorFaultSet, event::DriveFaultSet,
                                   event::RigFaultSet, event::FaultExpired, event::FaultsCleared, event::Tripped,
                                   event::SafeState, event::CmdLimited, event::Overrun, event::Stopped>;

// An event with the loop period and time it happened at.
struct LoopEvent {
  std::int64_t period = 0;
  double t_s = 0;
  LoopEventBody body = event::Stopped{};
};

enum class LoopEnd : std::uint8_t { running, completed, stopped, tripped };

// The loop's state for status requests; written every period, read from any thread.
struct LoopSnapshot {
  double t_s = 0;
  std::int64_t periods = 0, total_periods = 0;
  std::uint32_t flags = 0;
  LoopEnd end = LoopEnd::running;
  Trip trip = Trip::none;
  double gap_rad = kNaN, gap_override_rad = kNaN;
  SensorFault sensor = SensorFault::none;
  double sensor_value = 0, sensor_until_s = 0, drive_until_s = 0;  // until: +inf = until cleared
  std::int64_t overruns = 0, skipped_deadlines = 0, missed_reads = 0, limited_periods = 0;
  std::uint64_t rows_lost = 0, events_lost = 0;
  double p_meas_pa = kNaN, p_ref_pa = kNaN, theta_cmd_rad = kNaN;
};

class RunLoop {
 public:
  // Setup: builds the controller, keeps references (all must outlive the loop). wall_period is
  // the pacing period (the campaign's dT divided by the speed factor). now: the clock that times
  // the rig calls; nullptr in simulated time, where the loop keeps no timing statistics.
  RunLoop(const LoopProgramme& programme, const RunSpec& run, Rig& rig, const SafetyConfig& safety, const LoopConfig& loop,
          Clock::duration wall_period, SpscRing<TelemetryRecord>& telemetry, SpscRing<LoopEvent>& events,
          SpscRing<LoopRequest>& requests, TimedRig::NowFn now = &Clock::now);
  RunLoop(const RunLoop&) = delete;
  RunLoop& operator=(const RunLoop&) = delete;

  // Setup, after the rig is active: one reading gives the controller its initial state and the
  // first command (the drive's own target: no jump). Throws when the rig gives none.
  void begin(Clock::time_point now);

  // One period: requests, read, controller, safety, write, and the period's record. A period
  // without a usable reading records the last one again, with kFlagReadMissed set, so every row
  // parses. Real-time safe.
  void cycle(Clock::time_point deadline, Clock::time_point woke) noexcept;
  // The recorder's "cannot write" flag (Recorder::failed), checked every period; a set flag is a
  // fault like a full ring (see RecordingFaultPolicy). Setup, before the first cycle.
  void watch_recording(const std::atomic<bool>* failed) noexcept { recording_failed_ = failed; }
  // Closes the period: compute time (end - woke), overrun check, telemetry row, snapshot.
  // Returns false once the run is over. Real-time safe.
  bool finish_cycle(Clock::time_point end) noexcept;
  // The pacer skipped n deadlines that had passed before the loop could wake for them (after
  // an overrun, like cyclictest: no burst of late periods). Real-time safe.
  void skipped(std::int64_t n) noexcept { skipped_ += n; }

  Clock::duration wall_period() const noexcept { return wall_period_; }
  std::int64_t total_periods() const noexcept { return n_; }
  LoopEnd end() const noexcept { return end_; }
  LoopSnapshot snapshot() const noexcept { return snapshot_.load(); }  // any thread

  // After the loop thread has finished (or from it):
  Trip trip() const noexcept { return trip_; }
  double trip_t_s() const noexcept { return trip_t_s_; }
  double trip_value() const noexcept { return trip_value_; }
  double trip_limit() const noexcept { return trip_limit_; }
  const SafetyConfig& safety_config() const noexcept { return safety_.config(); }
  // The rig's last error when a rig fault or the watchdog tripped ("" otherwise).
  std::string_view trip_detail() const noexcept { return trip_detail_.data(); }
  std::uint64_t rows_pushed() const noexcept { return rows_pushed_; }
  std::uint64_t rows_lost() const noexcept { return rows_lost_; }
  std::uint64_t events_lost() const noexcept { return events_lost_; }
  std::int64_t overruns() const noexcept { return overruns_; }
  std::int64_t skipped_deadlines() const noexcept { return skipped_; }
  std::int64_t periods_run() const noexcept { return k_; }
  // The longest time between two periods' starts (a stalled host or loop: 0 before two periods)
  // and the t of the period that ended it.
  Clock::duration longest_gap() const noexcept { return longest_gap_; }
  double longest_gap_t_s() const noexcept { return longest_gap_t_s_; }
  // Any thread (status):
  const LatencyHistogram& wake_latency() const noexcept { return wake_latency_; }
  const LatencyHistogram& compute_time() const noexcept { return compute_; }
  const TimedRig& rig() const noexcept { return rig_; }

 private:
  void apply(const LoopRequest& r, double t_s) noexcept;
  void emit(double t_s, LoopEventBody body) noexcept;
  void enter_safe(Trip trip, double value, double limit, double t_s) noexcept;

  const LoopProgramme& c_;
  const RunSpec& run_;
  const ctl::Controller controller_;
  TimedRig rig_;
  const bool gap_to_rig_;  // the rig takes the programmed gap (Rig::programmable_gap)
  const bool timed_;       // on a clock (not simulated time): wake-up and compute times are kept,
                           // the snapshot is published every period
  Safety safety_;
  const LoopConfig loop_;
  TargetShaper shaper_;
  const Clock::duration wall_period_;
  const std::int64_t n_;
  SpscRing<TelemetryRecord>& telemetry_;
  SpscRing<LoopEvent>& events_;
  SpscRing<LoopRequest>& requests_;

  ctl::ControllerState cs_;
  ctl::ControllerOutputs out_;
  Schedule::Cursor ref_cursor_, gap_cursor_;
  plant::Rng rng_;
  std::int64_t k_ = 0;
  double last_sent_rad_ = 0;  // the last command the bench sent
  double last_p_meas_pa_ = kNaN;
  RigReading last_shown_;  // recorded again in periods without a reading
  bool limited_ = false;
  // Faults and overrides.
  double gap_override_rad_ = kNaN;
  SensorFault sensor_ = SensorFault::none;
  double sensor_value_ = 0, sensor_until_s_ = 0;
  bool drive_fault_ = false;
  double drive_until_s_ = 0, drive_frozen_rad_ = 0;
  bool rig_silent_ = false;
  // Safety and ending.
  bool safe_ = false;
  double safe_since_s_ = 0;
  bool abort_requested_ = false, stop_requested_ = false, overrun_trip_ = false, ring_full_ = false;
  const std::atomic<bool>* recording_failed_ = nullptr;
  Trip trip_ = Trip::none;
  double trip_t_s_ = kNaN, trip_value_ = kNaN, trip_limit_ = kNaN;
  std::array<char, 256> trip_detail_{};
  LoopEnd end_ = LoopEnd::running;
  // Statistics and the period in progress.
  LatencyHistogram wake_latency_, compute_;
  std::int64_t overruns_ = 0, overruns_in_a_row_ = 0, skipped_ = 0, missed_reads_ = 0, limited_periods_ = 0;
  std::uint64_t rows_pushed_ = 0, rows_lost_ = 0, events_lost_ = 0;
  Clock::time_point deadline_{}, woke_{};
  Clock::duration longest_gap_{};
  double longest_gap_t_s_ = kNaN;
  // The period's record, written where the recorder will read it: in the ring's next slot, or
  // in spare_ when the ring is full (the row is then lost, and counted). Composing it elsewhere
  // and copying it in cost a stall each period (the copy's wide loads waited for the narrow
  // stores just made: no store-to-load forwarding).
  TelemetryRecord spare_;
  TelemetryRecord* rec_ = &spare_;
  drv::Mailbox<LoopSnapshot> snapshot_;
};

}  // namespace hil::bench
