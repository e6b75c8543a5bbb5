#include "hil/line_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <string>
#include <system_error>
#include <vector>

namespace hil {

LineFile::LineFile(const std::filesystem::path& file, bool append) : path_(file) {
  fd_ = ::open(file.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC | (append ? 0 : O_TRUNC), 0644);
  if (fd_ < 0) throw std::system_error(errno, std::generic_category(), "cannot write " + file.string());
  struct stat st {};
  if (::fstat(fd_, &st) != 0 || !S_ISREG(st.st_mode)) {
    const int e = errno != 0 ? errno : EINVAL;
    ::close(fd_);
    fd_ = -1;
    throw std::system_error(e, std::generic_category(), file.string() + " is not a regular file");
  }
  size_ = static_cast<std::uint64_t>(st.st_size);
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

void replace_file(const std::filesystem::path& file, std::string_view text) {
  std::string name = ".";  // appended, not "." + ...: GCC 12 warns falsely (-Wrestrict) on that
  name += file.filename().string();
  name += ".tmp";
  const auto tmp = file.parent_path() / name;
  try {
    {
      LineFile out(tmp);
      out.append(text);
    }
    std::filesystem::rename(tmp, file);
  } catch (...) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw;
  }
}

}  // namespace hil
