// The telemetry recorder of one run: a writer thread drains the loop's telemetry and event rings
// into telemetry.csv (flushed every flush period, so a crash loses at most that much) and
// events.jsonl (one JSON object a line, written per event), and hands every row to a sink (the
// WebSocket stream). Memory is bounded by the rings; the loop counts what does not fit. Both
// files only ever hold whole lines (LineFile). The first write error stops the writing, sets
// failed() for the loop to see, and every row after it is counted as not written.
// Beside them, telemetry.mcap (telemetry_channels.hpp): the rows on the telemetry topic and the
// events on the events topic, in zstd chunks closed at every flush (a crash loses what the CSV
// loses), snapshots as metadata records (metadata()), and, once the run's record is final,
// run.json as an attachment and the summary (seal()). Its log times are wall-clock (LogClock,
// from start_clock()); a file its server died writing is finished by the next server
// (mark_interrupted_runs).
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "hil/bench/rt/rt_loop.hpp"
#include "hil/bench/rt/telemetry_channels.hpp"
#include "hil/line_file.hpp"
#include "hil/mcap.hpp"

namespace hil::bench {

// An event as written to events.jsonl (without "utc", which the logger adds).
nlohmann::json event_json(const LoopEvent& e);

class Recorder {
 public:
  using RowSink = std::function<void(const TelemetryRecord&)>;

  // Creates dir/telemetry.csv and dir/events.jsonl and starts the writer thread. Throws naming
  // the file when it cannot. with_truth: the rig is simulated (see ColumnSet in telemetry_record.hpp).
  Recorder(const std::filesystem::path& dir, const std::vector<std::pair<std::string, std::string>>& csv_metadata,
           std::size_t ring_rows, RowSink on_row = {}, std::chrono::milliseconds flush_period = std::chrono::milliseconds(100),
           bool with_truth = true, int avoid_cpu = -1);
  ~Recorder();
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  SpscRing<TelemetryRecord>& telemetry() noexcept { return telemetry_; }
  SpscRing<LoopEvent>& events() noexcept { return events_; }

  // An event from outside the loop (run start/end, rig setup, operator requests). Any thread.
  void log(const nlohmann::json& event);

  // A Metadata record in telemetry.mcap (the run's campaign, plant, rig). Any thread.
  void metadata(const std::string& name, const mcap::KeyValues& values);
  // Run time 0 is now, and the run goes at `speed` (run seconds per second): the log clock of
  // telemetry.mcap from here, said in its metadata record "clock". Called as the loop starts.
  void start_clock(double speed);
  LogClock clock() const noexcept;

  // Drains both rings, stops the writer thread and closes the CSV (telemetry.mcap stays open for
  // seal). Call after the loop thread has ended. Returns the first write error ("" when none);
  // never throws.
  std::string finish();
  // After finish: run.json (its final text) as an attachment of telemetry.mcap, then its summary
  // and footer. The destructor seals without an attachment when this was not called. Returns the
  // write error ("" when none); never throws.
  std::string seal(const std::string& run_json);

  std::uint64_t rows_written() const noexcept { return rows_written_.load(); }  // on disk
  // Taken from the ring but not on disk: refused by the disk, or arrived after the first failure.
  std::uint64_t rows_unwritten() const noexcept { return rows_unwritten_.load() + dropped_rows_.load(); }
  std::uint64_t events_written() const noexcept { return events_written_.load(); }
  std::uint64_t events_unwritten() const noexcept { return events_unwritten_.load(); }
  // Set once a write failed; the loop reads it every period (real-time safe to read).
  const std::atomic<bool>& failed() const noexcept { return failed_; }
  // The first write error ("" when none); from the thread that called finish().
  const std::string& error() const noexcept { return error_; }

 private:
  void writer(int avoid_cpu);
  bool drain();                        // one pass; true when it found anything
  void fail(const std::exception& e);  // the first write error
  void count_rows() noexcept;

  SpscRing<TelemetryRecord> telemetry_;
  SpscRing<LoopEvent> events_;
  std::unique_ptr<CsvWriter> csv_;
  std::unique_ptr<LineFile> events_file_;
  std::unique_ptr<mcap::Writer> mcap_;
  std::mutex mcap_mutex_;  // the writer thread (rows) and log() (events) both write it
  TelemetryChannel mcap_telemetry_;
  std::uint16_t mcap_rows_channel_ = 0, mcap_events_channel_ = 0;
  std::atomic<std::uint64_t> last_row_ns_{0};  // the last row's log time (run.json's attachment)
  std::atomic<std::uint64_t> clock_start_ns_{0};
  std::atomic<double> clock_speed_{1};
  std::mutex events_mutex_;  // log() is called from any thread
  RowSink on_row_;
  std::chrono::milliseconds flush_period_;
  bool with_truth_;
  std::vector<TelemetryRecord> batch_;
  std::string error_;
  std::atomic<bool> failed_{false};
  std::atomic<std::uint64_t> rows_written_{0}, rows_unwritten_{0}, dropped_rows_{0}, events_written_{0}, events_unwritten_{0};
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
  std::thread thread_;  // last: starts after everything above exists
};

}  // namespace hil::bench
