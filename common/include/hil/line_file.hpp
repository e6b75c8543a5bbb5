// An append-only text file that only ever holds whole lines: what a reader finds on disk after
// a full disk, a write error or a crash of the writer ends on '\n'. Telemetry and event logs
// are written through it. Not real-time safe: it does file I/O.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string_view>
#include <vector>

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

// Replaces `file` with `parts` written one after the other, all at once: written to a temporary
// beside it (".<name>.tmp<pid>-<n>", created exclusively, so two writers of the same file, in one
// process or two, never share one), then renamed over it. A reader sees the old file or a whole
// new one; of two concurrent writers the last rename wins, whole. On failure (full disk, no
// folder, a folder in the way) the temporary is removed and std::system_error thrown, naming
// `file` and the OS's reason; the old file stays. A file replaced keeps its permission bits; a
// link at `file` is replaced by the file, never followed (an output folder's link cannot send a
// write elsewhere).
void replace_file(const std::filesystem::path& file, std::span<const std::string_view> parts);
inline void replace_file(const std::filesystem::path& file, std::string_view text) {
  replace_file(file, std::span<const std::string_view>(&text, 1));
}

// Several files of one result (a report and its JSON) replaced together: every text is written
// to its temporary first, then all are renamed. A failure while writing (a full disk) leaves
// every old file as it was, never a new JSON beside an old report.
struct FileText {
  std::filesystem::path file;
  std::vector<std::string_view> parts;  // written one after the other; they must outlive the call
};
void replace_files(std::span<const FileText> files);

// Whether `candidate` is a temporary replace_file or replace_files wrote for `file` (beside it,
// ".<name>.tmp<pid>-<n>"): what a process that died before its rename left, whole or not.
bool is_temporary_of(const std::filesystem::path& candidate, const std::filesystem::path& file);

}  // namespace hil
