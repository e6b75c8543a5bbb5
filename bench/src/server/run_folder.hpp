// What the runner and the scan for interrupted runs both know of a run folder.
#pragma once

#include <filesystem>

namespace hil::bench {

// The event a run logs when its final run.json cannot be written (its outcome, reason, error).
inline constexpr const char* kFinalRecordUnwritten = "final_record_unwritten";

// A run folder's `.lock` (a hil::FileLock), held by the process running the run and released when
// it ends or dies: what tells a run that is running from one whose server is gone.
inline std::filesystem::path run_lock_file(const std::filesystem::path& dir) { return dir / ".lock"; }

}  // namespace hil::bench
