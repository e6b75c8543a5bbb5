#include "hil/bench/recorder.hpp"

#include <cmath>

#include <ctime>

#include "hil/bench/rt_thread.hpp"
#include "hil/units.hpp"

namespace hil::bench {
namespace {

using units::pa_to_mpa;
using units::rad_to_deg;

// JSON has no NaN: absent values become null.
nlohmann::json num(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

}  // namespace

nlohmann::json event_json(const LoopEvent& e) {
  using K = LoopEvent::Kind;
  nlohmann::json j;
  j["t_s"] = std::round(e.t_s * 1e6) / 1e6;
  j["period"] = e.period;
  switch (e.kind) {
    case K::gap_change:
      j["kind"] = "gap_change", j["source"] = "operator", j["gap_deg"] = num(rad_to_deg(e.a));
      break;
    case K::gap_programme:
      j["kind"] = "gap_programme", j["source"] = "operator";
      break;
    case K::sensor_fault:
      j["kind"] = "sensor_fault", j["source"] = "operator", j["mode"] = to_string(e.sensor);
      if (e.sensor == SensorFault::stuck) j["held_mpa"] = num(pa_to_mpa(e.a));
      if (e.sensor == SensorFault::bias) j["bias_kpa"] = num(e.a / 1e3);
      if (e.sensor == SensorFault::noise) j["rms_kpa"] = num(e.a / 1e3);
      j["duration_s"] = e.b > 0 ? num(e.b) : nlohmann::json(nullptr);
      break;
    case K::drive_fault:
      j["kind"] = "drive_fault", j["source"] = "operator", j["mode"] = "ignores_commands", j["on"] = e.a > 0;
      j["duration_s"] = e.b > 0 ? num(e.b) : nlohmann::json(nullptr);
      break;
    case K::rig_fault:
      j["kind"] = "rig_fault", j["source"] = "operator", j["mode"] = "silent", j["on"] = e.a > 0, j["accepted"] = e.b > 0;
      break;
    case K::fault_expired:
      j["kind"] = "fault_expired", j["source"] = "loop";
      j["fault"] = e.sensor == SensorFault::none ? std::string("drive") : "sensor " + std::string(to_string(e.sensor));
      break;
    case K::faults_cleared:
      j["kind"] = "faults_cleared", j["source"] = "operator";
      break;
    case K::trip:
      j["kind"] = "trip", j["source"] = "safety", j["reason"] = to_string(e.trip);
      if (e.trip == Trip::overpressure || e.trip == Trip::underpressure) {
        j["p_meas_mpa"] = num(pa_to_mpa(e.a)), j["limit_mpa"] = num(pa_to_mpa(e.b));
      } else if (e.trip == Trip::watchdog) {
        j["missed_in_a_row"] = num(e.a), j["limit"] = num(e.b);
      } else if (e.trip == Trip::overruns) {
        j["overruns_in_a_row"] = num(e.a), j["limit"] = num(e.b);
      }
      if (e.detail[0] != '\0') j["detail"] = std::string(e.detail.data());
      break;
    case K::safe_state:
      j["kind"] = "safe_state", j["source"] = "safety", j["theta_cmd_deg"] = num(rad_to_deg(e.a));
      break;
    case K::cmd_limited:
      j["kind"] = "cmd_limited", j["source"] = "safety", j["requested_deg"] = num(rad_to_deg(e.a)),
      j["sent_deg"] = num(rad_to_deg(e.b));
      break;
    case K::overrun:
      j["kind"] = "overrun", j["source"] = "loop", j["late_us"] = num(std::round(e.a * 10) / 10);
      break;
    case K::stopped:
      j["kind"] = "stopped", j["source"] = "operator";
      break;
  }
  return j;
}

Recorder::Recorder(const std::filesystem::path& dir, const std::vector<std::pair<std::string, std::string>>& csv_metadata,
                   std::size_t ring_rows, RowSink on_row, std::chrono::milliseconds flush_period, bool with_truth,
                   int avoid_cpu)
    : telemetry_(ring_rows),
      events_(4096),
      csv_(std::make_unique<CsvWriter>(dir / "telemetry.csv", loop_telemetry_columns(with_truth), csv_metadata)),
      events_file_(std::make_unique<LineFile>(dir / "events.jsonl")),
      on_row_(std::move(on_row)),
      flush_period_(flush_period),
      with_truth_(with_truth),
      batch_(4096) {
  csv_->flush();  // the header is on disk before the first row
  thread_ = std::thread([this, avoid_cpu] { writer(avoid_cpu); });
}

Recorder::~Recorder() { finish(); }

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
  for (std::size_t n; (n = telemetry_.pop(batch_.data(), batch_.size())) > 0;) {
    any = true;
    for (std::size_t i = 0; i < n; ++i) {
      if (!failed_.load(std::memory_order_relaxed)) {
        try {
          std::array<double, kLoopColumns> row;
          const std::size_t n = loop_telemetry_row(batch_[i], with_truth_, row);
          csv_->row(std::span<const double>(row.data(), n));
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
      } catch (const std::exception& e) {
        fail(e);
      }
      count_rows();
      last_flush = now;
    }
    if (stopping) break;
  }
  while (drain()) {
  }
  try {
    csv_->close();  // after a failure its buffer holds only rows from before it, if any
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
