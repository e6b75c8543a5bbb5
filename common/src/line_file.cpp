#include "hil/line_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <string>
#include <system_error>
#include <vector>

namespace hil {

LineFile::LineFile(const std::filesystem::path& file, bool append) : path_(file) {
  // O_NONBLOCK: a FIFO in the file's place (a hostile or mistaken folder) is refused below rather
  // than waited on for a reader forever; O_TRUNC only once it is known to be a regular file.
  fd_ = ::open(file.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC | O_NONBLOCK, 0644);
  if (fd_ < 0 && errno == ENXIO)
    throw std::system_error(errno, std::generic_category(), file.string() + " is not a regular file");
  if (fd_ < 0) throw std::system_error(errno, std::generic_category(), "cannot write " + file.string());
  struct stat st {};
  const auto fail = [&](int e, const std::string& what) {
    ::close(fd_);
    fd_ = -1;
    throw std::system_error(e, std::generic_category(), what);
  };
  if (::fstat(fd_, &st) != 0) fail(errno, "cannot write " + file.string());
  if (!S_ISREG(st.st_mode)) fail(EINVAL, file.string() + " is not a regular file");
  if (::fcntl(fd_, F_SETFL, 0) != 0 || (!append && ::ftruncate(fd_, 0) != 0)) fail(errno, "cannot write " + file.string());
  size_ = append ? static_cast<std::uint64_t>(st.st_size) : 0;
}

LineFile::~LineFile() {
  if (fd_ >= 0) ::close(fd_);
}

void LineFile::append(std::string_view lines) {
  std::size_t done = 0;
  while (done < lines.size()) {
    const ssize_t n = ::pwrite(fd_, lines.data() + done, lines.size() - done, static_cast<off_t>(size_ + done));
    if (n > 0) {
      done += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    const int e = n < 0 ? errno : ENOSPC;  // a write of 0 bytes: nothing more fits
    // Whatever part of these lines reached the disk goes again: the file ends where it ended.
    (void)::ftruncate(fd_, static_cast<off_t>(size_));
    throw std::system_error(e, std::generic_category(), "writing " + path_.string());
  }
  size_ += done;
}

std::uint64_t trim_to_whole_lines(const std::filesystem::path& file) {
  const int fd = ::open(file.c_str(), O_RDWR | O_CLOEXEC);
  if (fd < 0) throw std::system_error(errno, std::generic_category(), "cannot open " + file.string());
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode) || st.st_size == 0) {
    ::close(fd);
    return 0;
  }
  // Look back from the end, a block at a time, for the last '\n'.
  std::vector<char> block(4096);
  off_t end = st.st_size, keep = 0;
  while (end > 0 && keep == 0) {
    const off_t from = end > static_cast<off_t>(block.size()) ? end - static_cast<off_t>(block.size()) : 0;
    const ssize_t n = ::pread(fd, block.data(), static_cast<std::size_t>(end - from), from);
    if (n <= 0) break;
    for (ssize_t i = n - 1; i >= 0; --i) {
      if (block[static_cast<std::size_t>(i)] == '\n') {
        keep = from + i + 1;
        break;
      }
    }
    end = from;
  }
  const auto removed = static_cast<std::uint64_t>(st.st_size - keep);
  if (removed > 0 && ::ftruncate(fd, keep) != 0) {
    const int e = errno;
    ::close(fd);
    throw std::system_error(e, std::generic_category(), "cannot trim " + file.string());
  }
  ::close(fd);
  return removed;
}

namespace {

// The name of every temporary of `file` starts with this (".<name>.tmp").
std::string temporary_prefix(const std::filesystem::path& file) {
  std::string name = ".";  // hidden, and named after its target so a leftover explains itself
  name += file.filename().string();
  name += ".tmp";
  return name;
}

// Writes `parts` to a new temporary beside `file` and returns its path; on failure removes it and
// throws naming `file`.
std::filesystem::path write_temporary(const std::filesystem::path& file, std::span<const std::string_view> parts) {
  static std::atomic<unsigned> counter{0};  // keeps two writers in one process apart; O_EXCL, processes
  const auto dir = file.has_parent_path() ? file.parent_path() : std::filesystem::path(".");
  std::filesystem::path tmp;
  int fd = -1;
  for (int attempt = 0; attempt < 100 && fd < 0; ++attempt) {
    tmp = dir / (temporary_prefix(file) + std::to_string(::getpid()) + "-" + std::to_string(counter++));
    fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);  // the umask applies
    if (fd < 0 && errno != EEXIST) break;
  }
  if (fd < 0) throw std::system_error(errno, std::generic_category(), "cannot write " + file.string());
  int err = 0;
  // A file replaced keeps its permissions (a README made private stays private).
  struct stat old {};
  if (::lstat(file.c_str(), &old) == 0 && S_ISREG(old.st_mode) && ::fchmod(fd, old.st_mode & 07777) != 0) err = errno;
  for (const std::string_view part : parts) {
    std::size_t done = 0;
    while (done < part.size() && err == 0) {
      const ssize_t n = ::write(fd, part.data() + done, part.size() - done);
      if (n > 0) {
        done += static_cast<std::size_t>(n);
      } else if (n < 0 && errno == EINTR) {
        continue;
      } else {
        err = n < 0 ? errno : ENOSPC;  // a write of 0 bytes: nothing more fits
      }
    }
  }
  // No fsync: the rename makes the file appear whole to readers, which is what these records
  // need; surviving a power cut is not worth a disk flush per file of a sweep's thousands.
  if (::close(fd) != 0 && err == 0) err = errno;
  if (err != 0) {
    ::unlink(tmp.c_str());
    throw std::system_error(err, std::generic_category(), "cannot write " + file.string());
  }
  return tmp;
}

}  // namespace

bool is_temporary_of(const std::filesystem::path& candidate, const std::filesystem::path& file) {
  return candidate.parent_path() == file.parent_path() && candidate.filename().string().starts_with(temporary_prefix(file));
}

void replace_file(const std::filesystem::path& file, std::span<const std::string_view> parts) {
  const FileText one{file, {parts.begin(), parts.end()}};
  replace_files({&one, 1});
}

void replace_files(std::span<const FileText> files) {
  std::vector<std::filesystem::path> temporaries;
  const auto remove_temporaries = [&](std::size_t from) {
    for (std::size_t i = from; i < temporaries.size(); ++i) ::unlink(temporaries[i].c_str());
  };
  try {
    for (const auto& f : files) temporaries.push_back(write_temporary(f.file, f.parts));
  } catch (...) {
    remove_temporaries(0);  // nothing was replaced: every old file stays
    throw;
  }
  // Renames need no space: once every text is on disk they do not fail for a full disk.
  for (std::size_t i = 0; i < files.size(); ++i) {
    if (::rename(temporaries[i].c_str(), files[i].file.c_str()) != 0) {
      const int e = errno;
      remove_temporaries(i);
      throw std::system_error(e, std::generic_category(), "cannot write " + files[i].file.string());
    }
  }
}

}  // namespace hil
