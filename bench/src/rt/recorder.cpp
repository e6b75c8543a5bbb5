#include "hil/bench/rt/recorder.hpp"

#include <cmath>
#include <cstring>
#include <variant>

#include <ctime>

#include "hil/bench/rt/rt_thread.hpp"
#include "hil/units.hpp"

namespace hil::bench {
namespace {

using units::pa_to_mpa;
using units::rad_to_deg;

template <class... F>
struct Overloaded : F... {
  using F::operator()...;
};
template <class... F>
Overloaded(F...) -> Overloaded<F...>;  // clang 14 does not deduce aggregates without it

// JSON has no NaN: absent values become null.
nlohmann::json num(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

}  // namespace

nlohmann::json event_json(const LoopEvent& e) {
  nlohmann::json j;
  j["t_s"] = std::round(e.t_s * 1e6) / 1e6;
  j["period"] = e.period;
  auto duration = [](double s) { return s > 0 ? num(s) : nlohmann::json(nullptr); };  // 0: until cleared
  auto kind = [&j](const char* k, const char* source) { j["kind"] = k, j["source"] = source; };
  std::visit(
      Overloaded{
          [&](const event::GapChange& v) { kind("gap_change", "operator"), j["gap_deg"] = num(rad_to_deg(v.gap_rad)); },
          [&](const event::GapProgramme&) { kind("gap_programme", "operator"); },
          [&](const event::SensorFaultSet& v) {
            kind("sensor_fault", "operator"), j["mode"] = to_string(v.mode);
            if (v.mode == SensorFault::stuck) j["held_mpa"] = num(pa_to_mpa(v.value_pa));
            if (v.mode == SensorFault::bias) j["bias_kpa"] = num(v.value_pa / units::kPaPerKpa);
            if (v.mode == SensorFault::noise) j["rms_kpa"] = num(v.value_pa / units::kPaPerKpa);
            j["duration_s"] = duration(v.duration_s);
          },
          [&](const event::DriveFaultSet& v) {
            kind("drive_fault", "operator"), j["mode"] = "ignores_commands", j["on"] = v.on;
            j["duration_s"] = duration(v.duration_s);
          },
          [&](const event::RigFaultSet& v) {
            kind("rig_fault", "operator"), j["mode"] = "silent", j["on"] = v.on, j["accepted"] = v.accepted;
          },
          [&](const event::FaultExpired& v) {
            kind("fault_expired", "loop");
            j["fault"] = v.sensor == SensorFault::none ? std::string("drive") : "sensor " + std::string(to_string(v.sensor));
          },
          [&](const event::FaultsCleared&) { kind("faults_cleared", "operator"); },
          [&](const event::Tripped& v) {
            kind("trip", "safety"), j["reason"] = to_string(v.reason);
            if (v.reason == Trip::overpressure || v.reason == Trip::underpressure) {
              j["p_meas_mpa"] = num(pa_to_mpa(v.value)), j["limit_mpa"] = num(pa_to_mpa(v.limit));
            } else if (v.reason == Trip::watchdog) {
              j["missed_in_a_row"] = num(v.value), j["limit"] = num(v.limit);
            } else if (v.reason == Trip::overruns) {
              j["overruns_in_a_row"] = num(v.value), j["limit"] = num(v.limit);
            } else if (v.reason == Trip::following_error) {
              j["error_deg"] = num(rad_to_deg(v.value)), j["limit_deg"] = num(rad_to_deg(v.limit));
            }
            if (v.detail[0] != '\0') j["detail"] = std::string(v.detail.data(), strnlen(v.detail.data(), v.detail.size()));
          },
          [&](const event::SafeState& v) { kind("safe_state", "safety"), j["theta_cmd_deg"] = num(rad_to_deg(v.cmd_rad)); },
          [&](const event::CmdLimited& v) {
            kind("cmd_limited", "safety"), j["requested_deg"] = num(rad_to_deg(v.requested_rad));
            j["sent_deg"] = num(rad_to_deg(v.sent_rad));
          },
          [&](const event::Overrun& v) { kind("overrun", "loop"), j["late_us"] = num(std::round(v.late_us * 10) / 10); },
          [&](const event::Stopped&) { kind("stopped", "operator"); },
      },
      e.body);
  return j;
}

Recorder::Recorder(const std::filesystem::path& dir, const std::vector<std::pair<std::string, std::string>>& csv_metadata,
                   std::size_t ring_rows, RowSink on_row, std::chrono::milliseconds flush_period, bool with_truth, int avoid_cpu)
    : telemetry_(ring_rows),
      events_(4096),
      csv_(std::make_unique<CsvWriter>(dir / "telemetry.csv",
                                       telemetry_columns(with_truth ? ColumnSet::all : ColumnSet::measured), csv_metadata)),
      events_file_(std::make_unique<LineFile>(dir / "events.jsonl")),
      mcap_(std::make_unique<mcap::Writer>(dir / "telemetry.mcap", "")),
      mcap_telemetry_(telemetry_channel(with_truth ? ColumnSet::all : ColumnSet::measured)),
      on_row_(std::move(on_row)),
      flush_period_(flush_period),
      with_truth_(with_truth),
      batch_(4096) {
  csv_->flush();  // the header is on disk before the first row
  for (const TelemetryChannel* c : {static_cast<const TelemetryChannel*>(&mcap_telemetry_), &events_channel()}) {
    const std::uint16_t schema = mcap_->add_schema(schema_name(*c), "jsonschema", schema_json(*c));
    (c == &mcap_telemetry_ ? mcap_rows_channel_ : mcap_events_channel_) = mcap_->add_channel(schema, c->topic, "json");
  }
  clock_start_ns_.store(unix_now_ns());        // until start_clock: rows of a recorder used without a loop
  mcap_->metadata("telemetry", csv_metadata);  // what telemetry.csv's "# key: value" lines say
  mcap_->flush_chunk();
  thread_ = std::thread([this, avoid_cpu] { writer(avoid_cpu); });
}

Recorder::~Recorder() {
  finish();
  seal("");
}

void Recorder::metadata(const std::string& name, const mcap::KeyValues& values) {
  try {
    std::lock_guard lock(mcap_mutex_);
    if (mcap_ && !failed_.load()) mcap_->metadata(name, values);
  } catch (const std::exception& e) {
    fail(e);
  }
}

void Recorder::start_clock(double speed) {
  const LogClock c{unix_now_ns(), speed > 0 ? speed : 1.0};
  clock_start_ns_.store(c.start_unix_ns), clock_speed_.store(c.speed);
  metadata("clock", {{"log_time", "the wall clock (UTC, ns since 1970) at which the record was due: start_unix_ns + t_s / speed"},
                     {"start_unix_ns", std::to_string(c.start_unix_ns)},
                     {"speed", nlohmann::json(c.speed).dump()}});
}

LogClock Recorder::clock() const noexcept { return {clock_start_ns_.load(), clock_speed_.load()}; }

std::string Recorder::seal(const std::string& run_json) {
  std::unique_ptr<mcap::Writer> w;
  {
    std::lock_guard lock(mcap_mutex_);
    w = std::move(mcap_);  // events logged from now on go to events.jsonl only
  }
  if (!w) return "";
  try {
    if (failed_.load()) return error_;  // the writer's destructor keeps what is whole
    if (!run_json.empty()) w->attachment("run.json", "application/json", run_json, last_row_ns_.load());
    w->close();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

void Recorder::fail(const std::exception& e) {
  bool first = false;
  {
    std::lock_guard lock(events_mutex_);
    if (error_.empty()) error_ = e.what(), first = true;
  }
  if (first) failed_.store(true);
}

void Recorder::log(const nlohmann::json& event) {
  // {"utc":"2026-11-23T17:20:09.123456Z", then the event's own fields: the time it was written.
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  std::tm tm{};
  gmtime_r(&now.tv_sec, &tm);
  char utc[48];
  const std::size_t n = std::strftime(utc, sizeof utc, "{\"utc\":\"%Y-%m-%dT%H:%M:%S", &tm);
  std::snprintf(utc + n, sizeof utc - n, ".%06ldZ\",", now.tv_nsec / 1000);
  const std::string text = event.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  std::string line = utc;
  line.append(text, 1);  // "{...}": the opening brace is the prefix's
  line.push_back('\n');
  try {
    std::lock_guard lock(events_mutex_);
    if (!failed_.load()) {
      events_file_->append(line);
      events_written_.fetch_add(1);
      // The loop's events at their run time; the others (run start and end, requests) when written.
      const std::uint64_t t_ns =
          event.contains("t_s") && event["t_s"].is_number()
              ? clock().at(event["t_s"].get<double>())
              : static_cast<std::uint64_t>(now.tv_sec) * 1'000'000'000u + static_cast<std::uint64_t>(now.tv_nsec);
      std::lock_guard mcap_lock(mcap_mutex_);
      if (mcap_) mcap_->message(mcap_events_channel_, t_ns, std::string_view(line).substr(0, line.size() - 1));
      return;
    }
  } catch (const std::exception& e) {
    fail(e);
  }
  events_unwritten_.fetch_add(1);
}

bool Recorder::drain() {
  bool any = false;
  LoopEvent ev[64];
  for (std::size_t n; (n = events_.pop(ev, 64)) > 0;) {
    any = true;
    for (std::size_t i = 0; i < n; ++i) log(event_json(ev[i]));
  }
  const LogClock clock = this->clock();
  for (std::size_t n; (n = telemetry_.pop(batch_.data(), batch_.size())) > 0;) {
    any = true;
    for (std::size_t i = 0; i < n; ++i) {
      if (!failed_.load(std::memory_order_relaxed)) {
        try {
          TelemetryRow row;
          const std::size_t n = telemetry_row(batch_[i], with_truth_ ? ColumnSet::all : ColumnSet::measured, row);
          csv_->row(std::span<const double>(row.data(), n));
          // The same row in telemetry.mcap: the same columns and decimals (payload_json).
          const TelemetryRow full = telemetry_row(batch_[i]);
          const std::uint64_t t_ns = clock.at(batch_[i].step.t_s);
          last_row_ns_.store(t_ns, std::memory_order_relaxed);
          std::lock_guard mcap_lock(mcap_mutex_);  // released before a catch: fail() takes events_mutex_
          if (mcap_) mcap_->message(mcap_rows_channel_, t_ns, payload_json(mcap_telemetry_, full));
        } catch (const std::exception& e) {
          fail(e);
        }
      } else {
        rows_unwritten_.fetch_add(1, std::memory_order_relaxed);
      }
      if (on_row_) on_row_(batch_[i]);
    }
    count_rows();
  }
  return any;
}

// What is on disk and what the disk refused, from the CSV writer's own count.
void Recorder::count_rows() noexcept {
  rows_written_.store(csv_->rows_on_disk(), std::memory_order_relaxed);
  dropped_rows_.store(csv_->rows_dropped(), std::memory_order_relaxed);
}

void Recorder::writer(int avoid_cpu) {
  keep_off_cpu(avoid_cpu);  // the writer's I/O stays off the loop's CPU
  auto last_flush = std::chrono::steady_clock::now();
  for (;;) {
    bool stopping;
    {
      std::unique_lock lock(mutex_);
      wake_.wait_for(lock, std::chrono::milliseconds(5), [this] { return stop_; });
      stopping = stop_;
    }
    drain();
    const auto now = std::chrono::steady_clock::now();
    if (now - last_flush >= flush_period_ && !failed_.load()) {
      try {
        csv_->flush();
        std::lock_guard mcap_lock(mcap_mutex_);
        if (mcap_) mcap_->flush_chunk();  // a whole chunk per flush: what a crash leaves readable
      } catch (const std::exception& e) {
        fail(e);
      }
      count_rows();
      last_flush = now;
    }
    if (stopping) break;
  }
  while (drain()) {}
  try {
    csv_->close();  // after a failure its buffer holds only rows from before it, if any
    std::lock_guard mcap_lock(mcap_mutex_);
    if (mcap_ && !failed_.load()) mcap_->flush_chunk();
  } catch (const std::exception& e) {
    fail(e);
  }
  count_rows();
}

std::string Recorder::finish() {
  if (thread_.joinable()) {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    thread_.join();
  }
  return error_;
}

}  // namespace hil::bench
