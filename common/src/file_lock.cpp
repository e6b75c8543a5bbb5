#include "hil/file_lock.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <system_error>

namespace hil {

FileLock::FileLock(std::filesystem::path file, bool remove_when_released)
    : file_(std::move(file)), remove_(remove_when_released) {
  // O_NONBLOCK: a FIFO in the lock file's place is not waited on.
  fd_ = ::open(file_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NONBLOCK, 0644);
  if (fd_ < 0) throw std::system_error(errno, std::generic_category(), "cannot open " + file_.string());
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    const int e = errno;
    ::close(fd_);
    if (e == EWOULDBLOCK) throw Busy(file_.string() + " is locked by another process");
    throw std::system_error(e, std::generic_category(), "cannot lock " + file_.string());
  }
}

FileLock::~FileLock() {
  if (remove_) {
    std::error_code ec;
    std::filesystem::remove(file_, ec);
  }
  ::close(fd_);
}

bool FileLock::free(const std::filesystem::path& file) {
  const int fd = ::open(file.c_str(), O_RDWR | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) return true;  // never locked, or the lock file is gone: nobody holds it
  const bool unheld = ::flock(fd, LOCK_EX | LOCK_NB) == 0;
  ::close(fd);  // also releases it
  return unheld;
}

}  // namespace hil
