#include "hil/bench/recorder.hpp"

#include <cmath>

#include <spdlog/logger.h>
#include <spdlog/pattern_formatter.h>
#include <spdlog/sinks/basic_file_sink.h>

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
      on_row_(std::move(on_row)),
      flush_period_(flush_period),
      with_truth_(with_truth),
      batch_(4096) {
  csv_->flush();  // the header is on disk before the first row
  auto sink = std::make_shared<spdlog::sinks::basic_file_sink_mt>((dir / "events.jsonl").string(), true);
  log_ = std::make_shared<spdlog::logger>("events", std::move(sink));
  // The log record's own time becomes the "utc" field; the message is the rest of the object.
  log_->set_formatter(std::make_unique<spdlog::pattern_formatter>("{\"utc\":\"%Y-%m-%dT%H:%M:%S.%fZ\",%v",
                                                                  spdlog::pattern_time_type::utc));
  log_->flush_on(spdlog::level::trace);
  thread_ = std::thread([this, avoid_cpu] { writer(avoid_cpu); });
}

Recorder::~Recorder() { finish(); }

void Recorder::log(const nlohmann::json& event) {
  const std::string text = event.dump();  // "{...}": the formatter supplies the opening brace
  log_->info(std::string_view(text).substr(1));
  events_written_.fetch_add(1);
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
      if (error_.empty()) {
        try {
          std::array<double, kLoopColumns> row;
          const std::size_t n = loop_telemetry_row(batch_[i], with_truth_, row);
          csv_->row(std::span<const double>(row.data(), n));
          rows_written_.fetch_add(1, std::memory_order_relaxed);
        } catch (const std::exception& e) {
          error_ = e.what();
        }
      }
      if (!error_.empty()) rows_unwritten_.fetch_add(1, std::memory_order_relaxed);
      if (on_row_) on_row_(batch_[i]);
    }
  }
  return any;
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
    if (now - last_flush >= flush_period_ && error_.empty()) {
      try {
        csv_->flush();
      } catch (const std::exception& e) {
        error_ = e.what();
      }
      last_flush = now;
    }
    if (stopping) break;
  }
  while (drain()) {
  }
  try {
    csv_->close();
  } catch (const std::exception& e) {
    if (error_.empty()) error_ = e.what();
  }
  log_->flush();
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
