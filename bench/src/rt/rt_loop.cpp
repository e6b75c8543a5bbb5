#include "hil/bench/rt/rt_loop.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "hil/config.hpp"
#include "hil/units.hpp"

namespace hil::bench {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kRequestsPerPeriod = 8;  // more wait for the next period

double until(double t_s, double duration_s) noexcept { return duration_s > 0 ? t_s + duration_s : kInf; }

}  // namespace

LoopConfig LoopConfig::from_yaml(const cfg::Node& n) {
  n.allow_keys(
      {"priority", "cpu", "overrun", "ring_rows", "cpu_dma_latency_us", "io_priority", "recording_fault", "target_shaping"});
  LoopConfig c;
  // Each checked before it is narrowed to int (a cast first took 'priority: 4294967376' as 80).
  c.priority = static_cast<int>(n.integer_in("priority", 80, 0, 99, "0 = normal scheduling"));
  c.io_priority = static_cast<int>(n.integer_in("io_priority", 0, 0, 99, "0 = normal scheduling"));
  c.cpu = static_cast<int>(n.integer_in("cpu", -1, -1, 1023, "a CPU number, or -1 for no pinning"));
  if (const auto o = n.find("overrun")) {
    o->allow_keys({"policy", "abort_after"});
    const std::string policy = o->text("policy", "count");
    if (policy == "count") {
      c.overrun_policy = OverrunPolicy::count;
    } else if (policy == "abort") {
      c.overrun_policy = OverrunPolicy::abort;
    } else {
      o->at("policy").fail("must be 'count' or 'abort', got '" + policy + "'");
    }
    c.overrun_abort_after = static_cast<int>(o->integer_in("abort_after", 10, 1, 1'000'000, "overruns in a row"));
  }
  c.cpu_dma_latency_us = static_cast<int>(
      n.integer_in("cpu_dma_latency_us", 0, -1, 1'000'000, "microseconds; -1 leaves the CPUs' idle states alone"));
  const std::string recording = n.text("recording_fault", "safe_state");
  if (recording == "safe_state") {
    c.recording_fault = RecordingFaultPolicy::safe_state;
  } else if (recording == "count") {
    c.recording_fault = RecordingFaultPolicy::count;
  } else {
    n.at("recording_fault").fail("must be 'safe_state' or 'count', got '" + recording + "'");
  }
  if (const auto s = n.find("target_shaping")) {
    s->allow_keys({"max_velocity_deg_s", "max_acceleration_deg_s2"});
    const double v = s->number("max_velocity_deg_s"), a = s->number("max_acceleration_deg_s2");
    s->at("max_velocity_deg_s").require(v > 0 && v <= 1e5, "must be in (0, 100000] deg/s");
    s->at("max_acceleration_deg_s2").require(a > 0 && a <= 1e7, "must be in (0, 1e7] deg/s^2");
    c.target_shaping = {units::deg_to_rad(v), units::deg_to_rad(a)};
  }
  c.ring_rows = static_cast<int>(n.integer_in("ring_rows", 65536, 64, 1 << 24));
  return c;
}

// With shaped targets the compensator does not boost its jumps: the boost overdrives a lagging
// servo to cross the gap at its slew limit, while a shaped target already crosses at the drive's
// velocity limit; boosted, the shaper must brake from full speed when the boost is taken back,
// overshoots the flank and pushes the valve (stall per reversal x4 on paper_adaptive).
static ctl::ControllerParams shaped_params(ctl::ControllerParams p, const LoopConfig& loop) {
  if (loop.target_shaping.enabled()) p.traverse_boost = 0;
  return p;
}

std::string_view to_string(SensorFault f) noexcept {
  switch (f) {
    case SensorFault::none: return "none";
    case SensorFault::stuck: return "stuck";
    case SensorFault::dropout: return "dropout";
    case SensorFault::bias: return "bias";
    case SensorFault::noise: return "noise";
  }
  return "?";
}

RunLoop::RunLoop(const LoopProgramme& programme, const RunSpec& run, Rig& rig, const SafetyConfig& safety, const LoopConfig& loop,
                 Clock::duration wall_period, SpscRing<TelemetryRecord>& telemetry, SpscRing<LoopEvent>& events,
                 SpscRing<LoopRequest>& requests, TimedRig::NowFn now)
    : c_(programme),
      run_(run),
      controller_(shaped_params(run.controller, loop)),
      rig_(rig, now),
      gap_to_rig_(rig.programmable_gap()),
      timed_(now != nullptr),
      safety_(safety),
      loop_(loop),
      shaper_(loop.target_shaping),
      wall_period_(wall_period),
      n_(std::lround(programme.duration_s / programme.period_s)),
      telemetry_(telemetry),
      events_(events),
      requests_(requests),
      rng_(programme.seed ^ 0x5eed5eedULL) {
  if (wall_period_ <= Clock::duration::zero()) throw std::invalid_argument("loop period must be > 0");
}

void RunLoop::begin(Clock::time_point now) {
  RigReading rd;
  const RigStatus s = rig_.read(now, wall_period_, rd);
  if (s != RigStatus::ok || !std::isfinite(rd.p_meas_pa)) {
    throw std::runtime_error(std::string("rig '") + std::string(rig_.rig().kind()) +
                             "' gave no reading at the start of the run (" +
                             std::string(s == RigStatus::fault ? rig_.rig().health().last_error_text() : "no data") + ")");
  }
  const double theta0 = std::isfinite(rd.theta_target_rad) ? rd.theta_target_rad : rd.theta_motor_rad;
  if (!std::isfinite(theta0)) {
    throw std::runtime_error(std::string("rig '") + std::string(rig_.rig().kind()) +
                             "' reports neither a drive target nor a motor angle at the start of the run");
  }
  cs_ = controller_.initial_state(theta0, rd.p_meas_pa, run_.initial_touch);
  last_sent_rad_ = theta0;
  shaper_.reset(theta0);
  last_p_meas_pa_ = rd.p_meas_pa;
  last_shown_ = rd;
  LoopSnapshot snap;
  snap.total_periods = n_;
  snap.p_meas_pa = rd.p_meas_pa;
  snap.theta_cmd_rad = theta0;
  snapshot_.store(snap);
}

void RunLoop::emit(double t_s, LoopEventBody body) noexcept {
  if (!events_.try_push(LoopEvent{k_, t_s, body})) ++events_lost_;
}

void RunLoop::apply(const LoopRequest& r, double t_s) noexcept {
  using K = LoopRequest::Kind;
  switch (r.kind) {
    case K::stop: stop_requested_ = true; break;
    case K::abort: abort_requested_ = true; break;
    case K::set_gap:
      gap_override_rad_ = r.value;
      emit(t_s, event::GapChange{r.value});
      break;
    case K::programme_gap:
      gap_override_rad_ = kNaN;
      emit(t_s, event::GapProgramme{});
      break;
    case K::sensor_fault:
      sensor_ = r.sensor;
      sensor_value_ = r.sensor == SensorFault::stuck ? last_p_meas_pa_ : r.value;
      sensor_until_s_ = until(t_s, r.duration_s);
      emit(t_s, event::SensorFaultSet{r.sensor, sensor_value_, r.duration_s});
      break;
    case K::drive_fault:
      drive_fault_ = r.on;
      drive_frozen_rad_ = last_sent_rad_;
      drive_until_s_ = until(t_s, r.duration_s);
      emit(t_s, event::DriveFaultSet{r.on, r.duration_s});
      break;
    case K::rig_fault: {
      const bool accepted = rig_.rig().inject(RigFault::silent, r.on);
      if (accepted) rig_silent_ = r.on;
      emit(t_s, event::RigFaultSet{r.on, accepted});
      break;
    }
    case K::clear_faults:
      sensor_ = SensorFault::none;
      drive_fault_ = false;
      if (rig_silent_) rig_.rig().inject(RigFault::silent, false);
      rig_silent_ = false;
      emit(t_s, event::FaultsCleared{});
      break;
  }
}

void RunLoop::enter_safe(Trip trip, double value, double limit, double t_s) noexcept {
  safe_ = true;
  safe_since_s_ = t_s;
  trip_ = trip;
  trip_t_s_ = t_s;
  trip_value_ = value;
  trip_limit_ = limit;
  event::Tripped e{trip, value, limit};
  if (trip == Trip::rig_fault || trip == Trip::watchdog) {
    const RigHealth h = rig_.rig().health();  // what the device says went wrong, for the event
    static_assert(sizeof e.detail == sizeof h.last_error);
    e.detail = h.last_error;
    trip_detail_ = h.last_error;
  }
  emit(t_s, e);
}

void RunLoop::cycle(Clock::time_point deadline, Clock::time_point woke) noexcept {
  const double t = static_cast<double>(k_) * c_.period_s;
  if (timed_ && woke_ != Clock::time_point{} && woke - woke_ > longest_gap_) {
    longest_gap_ = woke - woke_;
    longest_gap_t_s_ = t;
  }
  deadline_ = deadline;
  woke_ = woke;
  const double dt = c_.period_s;
  std::uint32_t flags = 0;

  LoopRequest req;
  for (int i = 0; i < kRequestsPerPeriod && requests_.pop(&req, 1) == 1; ++i) apply(req, t);
  if (sensor_ != SensorFault::none && t >= sensor_until_s_) {
    emit(t, event::FaultExpired{sensor_});
    sensor_ = SensorFault::none;
  }
  if (drive_fault_ && t >= drive_until_s_) {
    emit(t, event::FaultExpired{SensorFault::none});
    drive_fault_ = false;
  }

  // Read, and what the injected sensor faults make of the reading.
  RigReading rd;
  const RigStatus status = rig_.read(woke, wall_period_, rd);
  bool missed = status != RigStatus::ok || !std::isfinite(rd.p_meas_pa);
  if (!missed) last_p_meas_pa_ = rd.p_meas_pa;  // what a stuck sensor freezes
  if (!missed && sensor_ != SensorFault::none) {
    switch (sensor_) {
      case SensorFault::stuck: rd.p_meas_pa = sensor_value_; break;
      case SensorFault::dropout:
        missed = true;
        rd.p_meas_pa = kNaN;
        break;
      case SensorFault::bias: rd.p_meas_pa += sensor_value_; break;
      case SensorFault::noise: rd.p_meas_pa += sensor_value_ * rng_.gaussian(); break;
      case SensorFault::none: break;
    }
    // What an injection made of it must still be a number: the record and the controller take
    // only numbers (a missed reading is held, and counted, like any other).
    if (!std::isfinite(rd.p_meas_pa)) missed = true;
  }
  if (missed) {
    rd = last_shown_;  // recorded as held; loop_flags says the reading was missed
  } else {
    last_shown_ = rd;
  }
  const double p_ref = c_.reference_pa.at(t, ref_cursor_);
  const double programmed_gap = c_.gap_rad.at(t, gap_cursor_);
  const double gap = std::isnan(gap_override_rad_) ? programmed_gap : gap_override_rad_;

  // Controller, then safety.
  double cmd = last_sent_rad_;
  out_.comp_rad = 0;
  out_.gap_measured = false;
  if (!safe_) {
    double value = kNaN, limit = kNaN;
    Trip trip = safety_.check(missed, status == RigStatus::fault, rd.p_meas_pa, value, limit);
    if (trip == Trip::none && abort_requested_) trip = Trip::operator_abort;
    if (trip == Trip::none && !missed && safety_.config().watches_following()) {
      // The shaper still holds last period's target: the one this reading answers.
      trip = safety_.follow(shaper_.position_rad(), rd.theta_motor_rad, dt, value, limit);
    }
    if (trip == Trip::none && overrun_trip_) {
      trip = Trip::overruns;
      value = static_cast<double>(overruns_in_a_row_);
      limit = loop_.overrun_abort_after;
    }
    if (trip == Trip::none && loop_.recording_fault == RecordingFaultPolicy::safe_state &&
        (ring_full_ || (recording_failed_ != nullptr && recording_failed_->load(std::memory_order_relaxed)))) {
      trip = Trip::recording;
      value = static_cast<double>(rows_lost_);
    }
    if (trip != Trip::none) {
      enter_safe(trip, value, limit, t);
    } else if (!missed) {
      controller_.step(cs_, {rd.p_meas_pa, p_ref, rd.theta_motor_rad}, out_);
      cmd = out_.theta_cmd_rad;
    }
  }
  if (safe_) {
    cmd = safety_.safe_command(last_sent_rad_, dt);
    if (safe_since_s_ == t) emit(t, event::SafeState{cmd});
    flags |= kFlagSafeState;
  } else {
    bool limited = false;
    const double requested = cmd;
    cmd = safety_.limit(requested, last_sent_rad_, dt, limited);
    if (limited) {
      flags |= kFlagCmdLimited;
      ++limited_periods_;
      if (!limited_) emit(t, event::CmdLimited{requested, cmd});
    }
    limited_ = limited;
  }

  // Write (a drive that ignores commands keeps the one it had), within the drive's limits.
  // Shaped per target the drive actually got: one the rig did not send is replaced, not stepped on.
  const double target = shaper_.step(drive_fault_ ? drive_frozen_rad_ : cmd, dt, rig_.rig().target_sent());
  rig_.write(woke, wall_period_, {target, true, gap_to_rig_ ? gap : kNaN});
  last_sent_rad_ = cmd;

  if (missed) {
    flags |= kFlagReadMissed;
    ++missed_reads_;
  }
  if (status == RigStatus::fault) flags |= kFlagDeviceFault;
  if (sensor_ != SensorFault::none) flags |= kFlagSensorFault;
  if (drive_fault_) flags |= kFlagDriveFault;
  if (rig_silent_) flags |= kFlagRigFault;
  if (!std::isnan(gap_override_rad_)) flags |= kFlagGapOverride;

  TelemetryRecord* const slot = telemetry_.claim();
  rec_ = slot != nullptr ? slot : &spare_;
  // Every field is written below or in finish_cycle (the slot holds an old row).
  static_assert(sizeof(TelemetryRecord) == sizeof(StepRecord) + 4 * sizeof(double), "a new field: write it here");
  StepRecord& r = rec_->step;
  r.t_s = t;
  r.p_ref_pa = p_ref;
  r.p_chamber_pa = rd.p_chamber_pa;
  r.p_meas_pa = rd.p_meas_pa;
  r.theta_cmd_rad = cmd;
  rec_->theta_target_rad = target;
  r.theta_motor_rad = rd.theta_motor_rad;
  r.theta_valve_rad = rd.theta_valve_rad;
  r.gap_true_rad = gap_to_rig_ ? gap : kNaN;
  r.gap_est_rad = out_.gap_est_rad;
  r.comp_rad = out_.comp_rad;
  r.touch = out_.touch_state;
  r.intention = out_.motion_intention;
  r.gap_measured = out_.gap_measured;
  rec_->wake_latency_us = std::chrono::duration<double, std::micro>(woke - deadline).count();
  rec_->flags = flags;
  if (timed_) wake_latency_.add(woke - deadline);
}

bool RunLoop::finish_cycle(Clock::time_point end) noexcept {
  if (timed_) compute_.add(end - woke_);
  TelemetryRecord& rec = *rec_;
  rec.compute_us = std::chrono::duration<double, std::micro>(end - woke_).count();
  const auto late = end - (deadline_ + wall_period_);
  if (late > Clock::duration::zero()) {
    rec.flags |= kFlagOverrun;
    ++overruns_;
    if (overruns_in_a_row_++ == 0) {
      emit(rec.step.t_s, event::Overrun{std::chrono::duration<double, std::micro>(late).count()});
    }
    if (loop_.overrun_policy == OverrunPolicy::abort && overruns_in_a_row_ >= loop_.overrun_abort_after) overrun_trip_ = true;
  } else {
    overruns_in_a_row_ = 0;
  }
  if (rec_ != &spare_) {
    telemetry_.publish();
    ++rows_pushed_;
  } else {
    ++rows_lost_;
    ring_full_ = true;
  }
  const double t = rec.step.t_s;
  ++k_;
  if (stop_requested_ && !safe_) {
    end_ = LoopEnd::stopped;
    emit(t, event::Stopped{});
  } else if (safe_ && t - safe_since_s_ + 0.5 * c_.period_s >= safety_.config().safe_hold_s) {
    end_ = LoopEnd::tripped;
  } else if (k_ >= n_ && !safe_) {
    end_ = LoopEnd::completed;
  }
  // In simulated time nobody asks for status while the run goes (the thread that runs it waits
  // for it): the last period's snapshot is enough, and the copy is a tenth of the loop's cost.
  if (!timed_ && end_ == LoopEnd::running) return true;

  LoopSnapshot snap;
  snap.t_s = t;
  snap.periods = k_;
  snap.total_periods = n_;
  snap.flags = rec.flags;
  snap.end = end_;
  snap.trip = trip_;
  snap.gap_rad = rec.step.gap_true_rad;
  snap.gap_override_rad = gap_override_rad_;
  snap.sensor = sensor_;
  snap.sensor_value = sensor_value_;
  snap.sensor_until_s = sensor_until_s_;
  snap.drive_until_s = drive_fault_ ? drive_until_s_ : 0;
  snap.overruns = overruns_;
  snap.skipped_deadlines = skipped_;
  snap.missed_reads = missed_reads_;
  snap.limited_periods = limited_periods_;
  snap.rows_lost = rows_lost_;
  snap.events_lost = events_lost_;
  snap.p_meas_pa = rec.step.p_meas_pa;
  snap.p_ref_pa = rec.step.p_ref_pa;
  snap.theta_cmd_rad = rec.step.theta_cmd_rad;
  snapshot_.store(snap);
  return end_ == LoopEnd::running;
}

}  // namespace hil::bench
