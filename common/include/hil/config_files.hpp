// Which files a result made from YAML configs depends on: the files cfg::Node::load_file read, each
// with what identifies its content on disk, so that a cache of the result can tell whether any of
// them has changed since (the server's GET /api/campaigns, /api/rigs and /api/models do not parse
// an unchanged file again).
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

namespace hil::cfg {

// A file as it was on disk: written, replaced, touched or removed, it has another stamp.
struct FileStamp {
  std::filesystem::path path;
  bool exists = false;
  std::uint64_t device = 0, inode = 0, bytes = 0;
  std::int64_t modified_ns = 0, changed_ns = 0;  // mtime and ctime, since the epoch
  bool operator==(const FileStamp&) const = default;
};

FileStamp stamp_of(const std::filesystem::path& file);

// Whether every file still is as it was stamped.
bool unchanged(const std::vector<FileStamp>& files);

// While one lives, the files Node::load_file reads on this thread are listed, stamped before they
// are read (a file that changes meanwhile shows as changed next time). Nested: each lists them.
class ReadFiles {
 public:
  ReadFiles();
  ~ReadFiles();
  ReadFiles(const ReadFiles&) = delete;
  ReadFiles& operator=(const ReadFiles&) = delete;

  const std::vector<FileStamp>& files() const { return files_; }
  // `file` is about to be read: Node::load_file's, and a loader's that reads a file a config names
  // by other means (a campaign's reference CSV).
  static void note(const std::filesystem::path& file);

 private:
  std::vector<FileStamp> files_;
  ReadFiles* outer_;
};

}  // namespace hil::cfg
