// A server's start: run folders whose run.json still says "running" although no live process
// holds their lock were left by a server that died. Each is given an honest record of what is on
// disk, and its telemetry.mcap its summary and footer. The folder is hostile input like any other: a symbolic link (the folder, its run.json,
// its telemetry or events) is never followed, so nothing outside the runs folder is read, trimmed
// or written, and run.json is bounded in size and nesting before it is parsed.
#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <functional>
#include <memory>
#include <optional>

#include <spdlog/spdlog.h>

#include "hil/bench/rt/run_folder.hpp"
#include "hil/bench/rt/run_record.hpp"
#include "hil/bench/server/runner.hpp"
#include "hil/file_lock.hpp"
#include "hil/line_file.hpp"
#include "request_guard.hpp"

namespace hil::bench {
namespace {

using nlohmann::json;
using SysClock = std::chrono::system_clock;

constexpr std::uint64_t kEventTailBytes = 64 * 1024;  // an event line is a few hundred bytes

// A plain file: not a symbolic link (whatever it points to), not a folder.
bool plain_file(const std::filesystem::path& p) {
  std::error_code ec;
  return std::filesystem::symlink_status(p, ec).type() == std::filesystem::file_type::regular;
}

// Telemetry rows in a run's CSV on disk: lines that are neither metadata (#) nor the header. Opened
// as every file of a run folder is (open_inside: no link, no FIFO or device), read in chunks.
std::uint64_t csv_rows(const std::filesystem::path& dir, const std::string& file) {
  const OpenedFile f = open_inside(dir, {file});
  const std::shared_ptr<const int> fd(new int(f.fd), [](const int* p) {
    ::close(*p);
    delete p;
  });
  std::uint64_t rows = 0;
  bool header = false, line_start = true, counted = false;
  constexpr std::size_t kChunk = 1 << 20;
  for (std::uint64_t at = 0;; at += kChunk) {
    const std::string chunk = read_at(*fd, at, kChunk, (dir / file).string());
    for (const char c : chunk) {
      if (line_start) {
        // A line counts once it has a first byte that is not '#' nor its end.
        counted = c == '#' || c == '\n';
        if (!counted && header) ++rows;
        if (!counted) header = true;
      }
      line_start = c == '\n';
    }
    if (chunk.size() < kChunk) break;
  }
  return rows;
}

// The last line of a run's events.jsonl when it is the kFinalRecordUnwritten event, else null.
json final_event_unrecorded(const std::filesystem::path& dir) {
  bool missing = false;
  const OpenedFile f = open_inside(dir, {"events.jsonl"}, &missing);
  if (missing) return nullptr;
  const std::shared_ptr<const int> fd(new int(f.fd), [](const int* p) {
    ::close(*p);
    delete p;
  });
  // Only its tail: an event log of a long run is large, and its last line is all that matters.
  const std::uint64_t from_byte = f.size > kEventTailBytes ? f.size - kEventTailBytes : 0;
  const std::string text = read_at(*fd, from_byte, static_cast<std::size_t>(f.size - from_byte), (dir / "events.jsonl").string());
  if (text.size() < 2) return nullptr;
  const auto from = text.rfind('\n', text.size() - 2);
  const json last =
      json::parse(text.begin() + static_cast<long>(from == std::string::npos ? 0 : from + 1), text.end(), nullptr, false);
  if (last.is_discarded() || !last.is_object() || last.value("kind", "") != kFinalRecordUnwritten) return nullptr;
  return last;
}

// What a server that died left of a replacement of run.json (replace_file writes
// ".run.json.tmp<pid>-<n>" whole, then renames it over run.json): the newest such file that reads
// as a run record; every such file is removed. It is the last thing that server said of the run:
// newer than a run.json that still says running, and all there is when the server died before
// its first rename (the folder then had no run.json and the run was listed nowhere).
std::optional<RunRecord> take_unrenamed_record(const std::filesystem::path& dir) {
  std::optional<RunRecord> newest;
  std::filesystem::file_time_type newest_time{};
  std::vector<std::filesystem::path> leftovers;
  std::error_code ec;
  for (const auto& f : std::filesystem::directory_iterator(dir, ec)) {
    if (plain_file(f.path()) && is_temporary_of(f.path(), dir / "run.json")) leftovers.push_back(f.path());
  }
  for (const auto& file : leftovers) {
    try {
      RunRecord r = RunRecord::from_json(read_json_inside(dir, {file.filename().string()}), file.string());
      const auto t = std::filesystem::last_write_time(file);
      if (!newest || t > newest_time) newest = std::move(r), newest_time = t;
    } catch (const std::exception& ex) {
      spdlog::warn("{}: a half-written run record of a server that died ({}); removed", file.string(), ex.what());
    }
    std::filesystem::remove(file, ec);
  }
  return newest;
}

// finish_run_mcap, said in the server's log.
json finish_mcap(const std::filesystem::path& dir) {
  json done = finish_run_mcap(dir);
  if (done.contains("error"))
    spdlog::error("{}: telemetry.mcap not finished: {}", dir.string(), done["error"].get<std::string>());
  if (done.contains("messages"))
    spdlog::warn("{}: telemetry.mcap of an interrupted run finished: {} messages in {} chunks, {} bytes of a cut record removed",
                 dir.string(), done["messages"].get<std::uint64_t>(), done["chunks"].get<std::uint64_t>(),
                 done["bytes_trimmed"].get<std::uint64_t>());
  return done;
}

}  // namespace

bool mark_interrupted_run(const std::filesystem::path& given, const std::string& found_by) {
  const std::filesystem::path dir = given.has_filename() ? given : given.parent_path();  // RUN/ as a shell completes it
  std::error_code ec;
  const auto type = std::filesystem::symlink_status(dir, ec).type();
  if (type != std::filesystem::file_type::directory || !FileLock::free(run_lock_file(dir))) return false;  // a live run
  const bool has_record = plain_file(dir / "run.json");
  std::optional<RunRecord> unrenamed;
  if (has_record || std::filesystem::exists(dir / ".reserve")) unrenamed = take_unrenamed_record(dir);
  if (!has_record && !unrenamed) {
    if (std::filesystem::remove(dir / ".reserve", ec)) {
      spdlog::warn("{}: a run folder whose process died before it wrote any record of the run; its reserve is freed",
                   dir.string());
    }
    return false;
  }
  RunRecord info;
  try {
    info = read_run_record_inside(dir);
  } catch (const std::exception& ex) {
    if (!unrenamed) {
      spdlog::warn("{}: unreadable run.json ({}); left as it is", dir.string(), ex.what());
      return false;
    }
  }
  if (unrenamed && (!has_record || info.outcome == Outcome::running)) {
    info = std::move(*unrenamed);
    spdlog::warn("{}: the record its process wrote last was not yet in place; taken as the run's record", dir.string());
    if (info.outcome != Outcome::running) {
      std::filesystem::remove(dir / ".reserve", ec);
      write_run_record(dir, info);
      return false;  // the run's end, as its process wrote it
    }
  }
  if (info.outcome == Outcome::interrupted) finish_mcap(dir);  // marked by a process that did not finish it
  if (info.outcome != Outcome::running) return false;
  try {
    // The reserve is freed first: on a full disk it is the room the lines below need.
    std::filesystem::remove(dir / ".reserve", ec);
    // What is on disk is the record: a line cut by the crash is removed and counted.
    json trimmed = json::object();
    for (const char* file : {"telemetry.csv", "events.jsonl"}) {
      if (plain_file(dir / file)) trimmed[file] = trim_to_whole_lines(dir / file);
    }
    const json mcap = finish_mcap(dir);  // its summary and footer: an indexed reader opens it
    if (mcap.contains("bytes_trimmed")) trimmed["telemetry.mcap"] = mcap["bytes_trimmed"];
    const auto csv = dir / "telemetry.csv";
    const std::uint64_t rows = plain_file(csv) ? csv_rows(dir, "telemetry.csv") : 0;
    const auto last_write = std::filesystem::last_write_time(plain_file(csv) ? csv : dir);
    const auto last_utc = std::chrono::time_point_cast<SysClock::duration>(std::chrono::file_clock::to_sys(last_write));
    const std::string found = utc_iso(SysClock::now());
    const std::string process = info.recorded_by.empty() ? "server" : info.recorded_by;
    const json end = plain_file(dir / "events.jsonl") ? final_event_unrecorded(dir) : json(nullptr);
    if (!end.is_null()) {  // the run ended; only its final run.json was not written
      info.outcome = outcome_from(end.value("outcome", "interrupted"));
      info.reason = (end["reason"].is_string() ? end["reason"].get<std::string>() + "; " : std::string()) +
                    "its final run.json could not be written (" + end.value("error", "?") +
                    ") and was restored from events.jsonl by " + found_by + " at " + found;
    } else {
      info.outcome = Outcome::interrupted;
      info.reason = "the " + process + " process (pid " + (info.pid > 0 ? std::to_string(info.pid) : std::string("?")) +
                    ") ended during the run, or could not write anything at its end; found by " + found_by + " at " + found;
    }
    info.stop_utc = utc_iso(last_utc);
    info.interrupted = {{"found_utc", found}, {"last_write_utc", utc_iso(last_utc)}, {"bytes_trimmed", trimmed}};
    if (!mcap.is_null()) info.interrupted["telemetry.mcap"] = mcap;
    // Only what the files show: the counts the dead process kept are unknown, and left out.
    RunRecord::Telemetry tel = info.telemetry.value_or(RunRecord::Telemetry{});
    tel.rows_written = rows;
    if (info.period_s > 0) tel.rows_expected = std::llround(info.duration_s / info.period_s);
    info.telemetry = tel;
    if (plain_file(dir / "events.jsonl")) {
      try {
        LineFile events(dir / "events.jsonl", /*append=*/true);
        events.append(
            json{{"utc", found}, {"kind", "interrupted"}, {"source", "bench"}, {"reason", *info.reason}, {"rows_on_disk", rows}}
                .dump() +
            "\n");
      } catch (const std::exception& ex) {
        // The record matters more than the event line: say so in it, and write it.
        info.interrupted["event_unwritten"] = ex.what();
        spdlog::error("{}: the interrupted event could not be appended ({}); the run's record says so", dir.string(), ex.what());
      }
    }
    write_run_record(dir, info);
    return true;
  } catch (const std::exception& ex) {
    spdlog::error("{}: cannot mark the interrupted run: {}", dir.string(), ex.what());
  }
  return false;
}

std::vector<std::filesystem::path> mark_interrupted_runs(const std::filesystem::path& runs_dir, const std::string& found_by) {
  std::vector<std::filesystem::path> marked;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(runs_dir, ec)) {
    if (mark_interrupted_run(e.path(), found_by)) marked.push_back(e.path());
  }
  std::sort(marked.begin(), marked.end());
  return marked;
}

std::optional<LastRun> newest_ended_run(const std::filesystem::path& runs_dir) {
  constexpr std::size_t kLooked = 50;  // folders without an ended record (analyses, a live run) passed over
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(runs_dir, ec)) {
    if (!e.is_symlink() && e.is_directory() && plain_file(e.path() / "run.json")) names.push_back(e.path().filename().string());
  }
  std::sort(names.begin(), names.end(), std::greater<>());
  for (std::size_t i = 0; i < names.size() && i < kLooked; ++i) {
    try {
      const RunRecord r = read_run_record_inside(runs_dir / names[i]);
      if (r.outcome != Outcome::running) return LastRun::of(names[i], r);
    } catch (const std::exception& ex) {
      spdlog::warn("{}: unreadable run.json ({}); not the last run", (runs_dir / names[i]).string(), ex.what());
    }
  }
  return std::nullopt;
}

}  // namespace hil::bench
