// A run's folder on disk, <runs_dir>/<UTC start>_<campaign>_<run>/, from its making to its final
// record: the lock that tells a running run from one whose process died, the space kept free so
// that a disk the telemetry filled still takes the run's honest end, and the first and final
// run.json (run_record.hpp). The recorder writes the telemetry and events beside it. Not real-time.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>

#include "hil/bench/rt/run_record.hpp"
#include "hil/file_lock.hpp"

namespace hil::bench {

// The runs folder has no room for a run's record (the API's 507).
class InsufficientStorage : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The event a run logs when its final run.json cannot be written (its outcome, reason, error).
inline constexpr const char* kFinalRecordUnwritten = "final_record_unwritten";

// A run folder's `.lock` (a hil::FileLock), held by the process running the run and released when
// it ends or dies: what tells a run that is running from one whose server is gone.
inline std::filesystem::path run_lock_file(const std::filesystem::path& dir) { return dir / ".lock"; }

// "2026-11-21T06:19:25.123Z": the time stamps of run.json, events and the server's jobs.
std::string utc_iso(std::chrono::system_clock::time_point t);

// Refused before anything runs rather than tripped later: throws InsufficientStorage (naming the
// folder, the space free and needed) when `runs_dir` (made if absent) cannot hold `runs` records of
// `rows_per_run` telemetry rows each, with their reserves.
void check_room_for_runs(const std::filesystem::path& runs_dir, double rows_per_run, std::size_t runs);

// The telemetry.mcap of a run whose process died, given its summary and footer
// (mcap::Writer::finish: the crash's cut tail removed, nothing whole). What was done, for the
// run's interrupted record: {"bytes_trimmed", "chunks", "messages", "indexes_rebuilt"}, or
// {"was_whole": true}, or {"error": why it is left as it is}; null when the folder has no such
// plain file (a symbolic link is never followed). Never throws.
nlohmann::json finish_run_mcap(const std::filesystem::path& dir);

class RunFolder {
 public:
  // Makes <runs_dir>/<UTC start>_<campaign>_<run>/ (with _2, _3... when taken), takes its lock,
  // reserves its space and writes the first run.json (`first`). On any failure the folder is
  // removed (a folder without run.json would be no run at all) and the error thrown:
  // InsufficientStorage when the space cannot be reserved.
  RunFolder(const std::filesystem::path& runs_dir, std::chrono::system_clock::time_point start_utc, const std::string& campaign,
            const std::string& run, const RunRecord& first);
  RunFolder(const RunFolder&) = delete;
  RunFolder& operator=(const RunFolder&) = delete;

  const std::filesystem::path& dir() const noexcept { return dir_; }
  // The final run.json, atomically; the reserve is given back for it first. Throws as
  // write_run_record when the disk refuses it (run.json then still says "running").
  void write_final(const RunRecord& record);
  // The run is over: its lock goes (and the lock file with it).
  void release() noexcept { lock_.reset(); }

 private:
  std::filesystem::path dir_;
  std::optional<FileLock> lock_;
};

}  // namespace hil::bench
