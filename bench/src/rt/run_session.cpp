#include "hil/bench/rt/run_session.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <semaphore>
#include <thread>

#include <spdlog/spdlog.h>

#include "hil/units.hpp"

namespace hil::bench {
namespace {

using nlohmann::json;

std::string fmt(const char* format, double a, double b = 0, double c = 0) {
  char buf[200];
  std::snprintf(buf, sizeof buf, format, a, b, c);
  return buf;
}

// The reason of a trip in the operator's words.
std::string describe_trip(const RunLoop& loop) {
  const double t = loop.trip_t_s();
  switch (loop.trip()) {
    case Trip::overpressure:
      return fmt("overpressure: p_meas %.4f MPa above the %.4f MPa limit at t = %.3f s", units::pa_to_mpa(loop.trip_value()),
                 units::pa_to_mpa(loop.trip_limit()), t);
    case Trip::underpressure:
      return fmt("underpressure: p_meas %.4f MPa below the %.4f MPa limit at t = %.3f s", units::pa_to_mpa(loop.trip_value()),
                 units::pa_to_mpa(loop.trip_limit()), t);
    case Trip::watchdog: {
      // What the rig says the reads waited on ("transducer: newest reading 41.0 ms old (limit 4.0
      // ms): ...: ILLEGAL DATA ADDRESS (exception 2)"): the count alone named no cause.
      const std::string detail(loop.trip_detail());
      return fmt("watchdog: %.0f rig reads missed in a row at t = %.3f s", loop.trip_value(), t) +
             (detail.empty() ? "" : ": " + detail);
    }
    case Trip::rig_fault: return fmt("rig fault at t = %.3f s: ", t) + std::string(loop.trip_detail());
    case Trip::overruns:
      return fmt("overruns: %.0f periods in a row ended after their next deadline at t = %.3f s", loop.trip_value(), t);
    case Trip::operator_abort: return "operator abort";
    case Trip::recording: return fmt("recording: telemetry could not be recorded at t = %.3f s", t);
    case Trip::following_error:
      return fmt("following error: the drive's position %+.3f deg from its target, beyond the %.3f deg limit for %.0f ms",
                 units::rad_to_deg(loop.trip_value()), units::rad_to_deg(loop.trip_limit()),
                 loop.safety_config().following_error_s * 1000) +
             fmt(" in a row at t = %.3f s (a frozen encoder, a jammed gear or a drive that stopped following)", t);
    case Trip::none: break;
  }
  return "none";
}

// After a rig's deactivate(): when the drive could not be switched off, says so everywhere an
// operator looks (the reason, an event, the log): it may still be enabled, with the motor
// attached. True when it could not.
bool say_drive_not_disabled(const Rig& rig, Recorder& rec, std::string& reason) {
  const std::string why = rig.deactivate_failure();
  if (why.empty()) return false;
  const std::string text = "switching the drive off failed (" + why + "): it may still be enabled";
  spdlog::error("{}", text);
  rec.log({{"kind", "drive_not_disabled"}, {"source", "bench"}, {"detail", text}});
  reason += (reason.empty() ? "" : "; ") + text;
  return true;
}

}  // namespace

json loop_stats_json(const RunLoop& loop) {
  return {{"periods", loop.snapshot().periods},
          {"overruns", loop.snapshot().overruns},
          {"skipped_deadlines", loop.snapshot().skipped_deadlines},
          {"missed_reads", loop.snapshot().missed_reads},
          {"limited_periods", loop.snapshot().limited_periods},
          {"wake_latency_us", loop.wake_latency().summary().to_json()},
          {"longest_gap_ms", std::chrono::duration<double, std::milli>(loop.longest_gap()).count()},
          {"longest_gap_t_s", std::isfinite(loop.longest_gap_t_s()) ? json(loop.longest_gap_t_s()) : json(nullptr)},
          {"compute_us", loop.compute_time().summary().to_json()},
          {"rig_read_us", loop.rig().read_time().summary().to_json()},
          {"rig_write_us", loop.rig().write_time().summary().to_json()}};
}

RunSession::RunSession(Rig& rig, const RigConfig& rig_config, const LoopProgramme& programme, const RunSpec& run, double speed,
                       Recorder& recorder, std::string mlock_warning)
    : rig_(rig),
      rc_(rig_config),
      programme_(programme),
      run_(run),
      speed_(speed),
      rec_(recorder),
      mlock_warning_(std::move(mlock_warning)),
      requests_(64) {}

RunSession::~RunSession() = default;

bool RunSession::set_up(const RunSessionHooks& hooks) {
  // From here an abort cuts the setup short; one that came before is passed on at once (the hook).
  if (hooks.in_setup) hooks.in_setup(&rig_);
  const LoopProgramme& c = programme_;
  try {
    Schedule::Cursor rc0, gc0;
    rig_.configure({&c, c.period_s, c.reference_pa.at(0.0, rc0), c.gap_rad.at(0.0, gc0)});
    rig_.activate();
    const auto wall = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(c.period_s / speed_));
    loop_ = std::make_unique<RunLoop>(c, run_, rig_, rc_.safety, rc_.loop, wall, rec_.telemetry(), rec_.events(), requests_);
    loop_->watch_recording(&rec_.failed());
    loop_->begin(Clock::now());
  } catch (const std::exception& e) {
    outcome_ = Outcome::error;
    reason_ = std::string("rig '") + rc_.name + "' setup: " + e.what();
    rec_.log({{"kind", "rig_error"}, {"source", "bench"}, {"detail", reason_}});
    // The setup ended because of an abort (or would have been cut short by it).
    if (const auto abort = hooks.abort_reason ? hooks.abort_reason() : std::nullopt) {
      outcome_ = Outcome::aborted;
      reason_ = *abort + " during the setup of rig '" + rc_.name + "' (" + e.what() + ")";
    }
    rig_.deactivate();
    say_drive_not_disabled(rig_, rec_, reason_);
    loop_.reset();
  }
  if (hooks.in_setup) hooks.in_setup(nullptr);
  return loop_ != nullptr;
}

void RunSession::run_loop(const RunSessionHooks& hooks) {
  std::optional<CpuLatencyRequest> cpu_latency;
  if (rc_.loop.cpu_dma_latency_us >= 0) {
    cpu_latency.emplace(rc_.loop.cpu_dma_latency_us);
    if (!cpu_latency->warning().empty()) spdlog::warn("{}", cpu_latency->warning());
  }
  std::binary_semaphore go(0);
  std::thread t([&] {
    go.acquire();
    prefault_stack();
    run_paced(*loop_, Clock::now());
  });
  rt_ = make_realtime(t, rc_.loop.priority, rc_.loop.cpu);
  if (!rt_.warning.empty()) spdlog::warn("loop thread: {}", rt_.warning);
  rec_.log({{"kind", "loop_start"},
            {"source", "bench"},
            {"sched", rt_.describe()},
            {"warning", rt_.warning},
            {"mlock_warning", mlock_warning_},
            {"cpu_dma_latency",
             cpu_latency ? (cpu_latency->warning().empty() ? json(rc_.loop.cpu_dma_latency_us) : json(cpu_latency->warning()))
                         : json(nullptr)}});
  if (hooks.loop_ready) hooks.loop_ready(*loop_, requests_, rt_);
  rec_.start_clock(speed_);  // the loop's run time 0, as it starts below
  go.release();
  t.join();
  switch (loop_->end()) {
    case LoopEnd::completed: outcome_ = Outcome::completed; break;
    case LoopEnd::stopped: outcome_ = Outcome::stopped, reason_ = "operator stop"; break;
    case LoopEnd::tripped:
    case LoopEnd::running:
      outcome_ = Outcome::aborted;
      if (loop_->trip() == Trip::operator_abort) {
        const auto abort = hooks.abort_reason ? hooks.abort_reason() : std::nullopt;
        reason_ = abort ? *abort : "operator abort";
      } else {
        reason_ = describe_trip(*loop_);
        // A stalled loop (a busy host, a hung controller) explains many trips: said beside one when
        // it was long against the period (it is in run.json's trip either way).
        const double gap_ms = std::chrono::duration<double, std::milli>(loop_->longest_gap()).count();
        const double period_ms = std::chrono::duration<double, std::milli>(loop_->wall_period()).count();
        if (gap_ms >= 50 && gap_ms > 10 * period_ms) {
          reason_ += fmt("; the loop's longest gap between two periods was %.0f ms (%.0f periods) at t = %.3f s", gap_ms,
                         gap_ms / period_ms, loop_->longest_gap_t_s());
        }
      }
      break;
  }
  deactivate();
  cpu_latency.reset();
}

// How the rig's devices ended the run (read before they are switched off), then off.
void RunSession::deactivate() {
  const RigHealth h = rig_.health();
  rig_health_ = {{"connected", h.connected},
                 {"fault", h.fault},
                 {"reads", h.reads},
                 {"stale_reads", h.stale_reads},
                 {"fault_reads", h.fault_reads},
                 {"reconnects", h.reconnects},
                 {"reconnects_by_device", {{"drive", h.drive_reconnects}, {"transducer", h.transducer_reconnects}}},
                 {"last_error", std::string(h.last_error_text())}};
  rig_.deactivate();
  if (const drv::SwitchOff off = rig_.switch_off(); !off.path.empty()) {
    // Which path switched the drive off, what asked, how long it took, the state read back.
    rig_health_["switch_off"] = {
        {"path", off.path}, {"asked_by", off.asked_by}, {"after_ms", off.after_ms}, {"state", off.state}, {"off", off.off}};
  }
  if (say_drive_not_disabled(rig_, rec_, reason_)) {
    rig_health_["disable_error"] = rig_.deactivate_failure();
    if (outcome_ == Outcome::completed) outcome_ = Outcome::error;  // the run is over, the drive may not be
  }
}

void RunSession::run(const RunSessionHooks& hooks) {
  if (set_up(hooks)) run_loop(hooks);
  write_error_ = rec_.finish();
  if (loop_ && loop_->trip() == Trip::recording) {
    reason_ += write_error_.empty()
                   ? fmt(": the telemetry ring was full (%.0f rows lost)", static_cast<double>(loop_->rows_lost()))
                   : ": " + write_error_;
  } else if (!write_error_.empty() && outcome_ == Outcome::completed) {
    outcome_ = Outcome::error, reason_ = "telemetry: " + write_error_;
  }
  const std::uint64_t rows_not_recorded = rec_.rows_unwritten() + (loop_ ? loop_->rows_lost() : 0);
  if (rows_not_recorded > 0 && !reason_.empty())
    reason_ += fmt("; %.0f rows not recorded", static_cast<double>(rows_not_recorded));
}

void RunSession::record_end(RunRecord& info) const {
  info.outcome = outcome_;
  if (!reason_.empty()) info.reason = reason_;
  info.ended = true;
  info.rig_health = rig_health_;
  if (loop_) {
    const RunLoop& loop = *loop_;
    if (loop.trip() != Trip::none) {
      info.trip = RunRecord::Trip{std::string(to_string(loop.trip())),
                                  loop.trip_t_s(),
                                  std::isfinite(loop.trip_value()) ? std::optional(loop.trip_value()) : std::nullopt,
                                  std::isfinite(loop.trip_limit()) ? std::optional(loop.trip_limit()) : std::nullopt,
                                  std::chrono::duration<double, std::milli>(loop.longest_gap()).count(),
                                  std::isfinite(loop.longest_gap_t_s()) ? std::optional(loop.longest_gap_t_s()) : std::nullopt};
    }
    info.periods_run = loop.periods_run();
    json stats = loop_stats_json(loop);
    stats["sched"] = rt_.describe();
    stats["rt_warning"] = rt_.warning;
    stats["memory_locked"] = mlock_warning_.empty();
    stats["cpu_dma_latency_us"] = rc_.loop.cpu_dma_latency_us;
    stats["overrun_policy"] = rc_.loop.overrun_policy == OverrunPolicy::abort ? "abort" : "count";
    stats["wall_period_us"] = std::chrono::duration<double, std::micro>(loop.wall_period()).count();
    info.loop = stats;
  }
  RunRecord::Telemetry tel;
  tel.rows_written = rec_.rows_written();
  tel.rows_lost = loop_ ? loop_->rows_lost() : 0;
  tel.rows_unwritten = rec_.rows_unwritten();
  tel.events_lost = loop_ ? loop_->events_lost() : 0;
  tel.events_unwritten = rec_.events_unwritten();
  tel.ring_rows = rec_.telemetry().capacity();
  tel.write_error_known = true;
  if (!write_error_.empty()) tel.write_error = write_error_;
  info.telemetry = tel;
}

}  // namespace hil::bench
