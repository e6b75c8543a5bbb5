#include "hil/bench/rt/run_folder.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>

#include "hil/mcap.hpp"

namespace hil::bench {
namespace {

using SysClock = std::chrono::system_clock;

// Space kept free in each run folder while the run lasts, and given back just before the final
// run.json is written: so a disk that the telemetry filled still takes the run's honest record.
constexpr std::uintmax_t kReserveBytes = 1u << 20;
// A loop telemetry row in telemetry.csv (about 110-140 characters) and in telemetry.mcap (about
// 60 bytes in zstd chunks with its index entry: paper_adaptive's 18 000 rows made 1.1 MB; 410
// uncompressed). The estimate keeps the uncompressed size: a disk is never judged by how well
// a run's data compresses.
constexpr double kBytesPerRow = 560;

std::string utc(SysClock::time_point t, const char* format) {
  const std::time_t s = SysClock::to_time_t(t);
  std::tm tm{};
  gmtime_r(&s, &tm);
  char buf[64];
  std::strftime(buf, sizeof buf, format, &tm);
  return buf;
}

std::filesystem::path unique_dir(const std::filesystem::path& base) {
  std::filesystem::path p = base;
  for (int i = 2; std::filesystem::exists(p); ++i) p = base.string() + "_" + std::to_string(i);
  std::filesystem::create_directories(p);
  return p;
}

}  // namespace

std::string utc_iso(SysClock::time_point t) {
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(t.time_since_epoch()).count() % 1000;
  char frac[8];
  std::snprintf(frac, sizeof frac, ".%03dZ", static_cast<int>(ms));
  return utc(t, "%Y-%m-%dT%H:%M:%S") + frac;
}

void check_room_for_runs(const std::filesystem::path& runs_dir, double rows_per_run, std::size_t runs) {
  const double rows = rows_per_run * static_cast<double>(runs);
  const double need = rows * kBytesPerRow + static_cast<double>(runs) * 2.0 * kReserveBytes;
  std::error_code ec;
  std::filesystem::create_directories(runs_dir, ec);
  const auto space = std::filesystem::space(runs_dir, ec);
  if (ec) throw InsufficientStorage("cannot use the runs folder " + runs_dir.string() + ": " + ec.message());
  if (static_cast<double>(space.available) < need) {
    char buf[200];
    std::snprintf(buf, sizeof buf,
                  "the runs folder has %.1f MB free; this campaign's record needs about %.1f MB (%.0f telemetry rows)",
                  static_cast<double>(space.available) / 1e6, need / 1e6, rows);
    throw InsufficientStorage(buf + (" in " + runs_dir.string()));
  }
}

RunFolder::RunFolder(const std::filesystem::path& runs_dir, SysClock::time_point start_utc, const std::string& campaign,
                     const std::string& run, const RunRecord& first)
    : dir_(unique_dir(runs_dir / (utc(start_utc, "%Y%m%dT%H%M%SZ") + "_" + campaign + "_" + run))) {
  try {
    lock_.emplace(run_lock_file(dir_), /*remove_when_released=*/true);
    // The reserve is taken first: a disk without room for it would not take the run's record.
    const int fd = ::open((dir_ / ".reserve").c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
    const int rc = fd < 0 ? errno : ::posix_fallocate(fd, 0, static_cast<off_t>(kReserveBytes));
    if (fd >= 0) ::close(fd);
    if (rc != 0) throw InsufficientStorage(std::string("cannot reserve space in ") + dir_.string() + ": " + std::strerror(rc));
    write_run_record(dir_, first);
  } catch (...) {
    lock_.reset();
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
    throw;
  }
}

void RunFolder::write_final(const RunRecord& record) {
  std::error_code ec;
  std::filesystem::remove(dir_ / ".reserve", ec);  // its room is for this last write
  write_run_record(dir_, record);
}

nlohmann::json finish_run_mcap(const std::filesystem::path& dir) {
  const auto file = dir / "telemetry.mcap";
  std::error_code ec;
  if (std::filesystem::symlink_status(file, ec).type() != std::filesystem::file_type::regular) return nullptr;
  try {
    const mcap::Finished f = mcap::Writer::finish(file);
    if (f.was_whole) return {{"was_whole", true}};
    return {
        {"bytes_trimmed", f.bytes_cut}, {"chunks", f.chunks}, {"messages", f.messages}, {"indexes_rebuilt", f.indexes_rebuilt}};
  } catch (const std::exception& e) {
    return {{"error", e.what()}};
  }
}

}  // namespace hil::bench
