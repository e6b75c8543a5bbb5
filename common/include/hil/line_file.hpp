// An append-only text file that only ever holds whole lines: what a reader finds on disk after
// a full disk, a write error or a crash of the writer ends on '\n'. Telemetry and event logs
// are written through it. Not real-time safe: it does file I/O.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string_view>

namespace hil {

class LineFile {
 public:
  // Creates (truncating) or, with append, opens `file`. Throws std::system_error naming the file.
  explicit LineFile(const std::filesystem::path& file, bool append = false);
  ~LineFile();
  LineFile(const LineFile&) = delete;
  LineFile& operator=(const LineFile&) = delete;

  // Writes `lines` (whole lines, the last ending in '\n') at the end of the file. When the disk
  // takes only part of them (full, quota, I/O error) the file is cut back to its previous end and
  // this throws std::system_error naming the file and the OS's reason: all or nothing.
  void append(std::string_view lines);
  std::uint64_t bytes() const noexcept { return size_; }
  const std::filesystem::path& path() const noexcept { return path_; }

 private:
  std::filesystem::path path_;
  int fd_ = -1;
  std::uint64_t size_ = 0;  // bytes on disk, always at a line boundary
};

// Cuts `file` back to its last '\n' (a line left half-written by a process that died in the
// middle of a write). Returns how many bytes were removed; 0 when it already ended whole.
std::uint64_t trim_to_whole_lines(const std::filesystem::path& file);

// Replaces `file` with `text` all at once: written through a LineFile to ".<name>.tmp" beside it,
// then renamed over it, so a reader sees the old file or the whole new one. On failure the
// temporary is removed and the error thrown; the old file stays.
void replace_file(const std::filesystem::path& file, std::string_view text);

}  // namespace hil
