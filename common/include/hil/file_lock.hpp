// An exclusive advisory lock (flock) on a file, held while the object lives: the one way our
// processes keep a folder to themselves (a run folder while its server runs it, a sweep's rows
// file while one sweep writes it). The kernel drops it with the descriptor, so a process that
// dies holds nothing, and a later one can tell a live holder from a dead one. Not real-time safe.
#pragma once

#include <filesystem>
#include <stdexcept>

namespace hil {

class FileLock {
 public:
  // Another process holds the lock.
  class Busy : public std::runtime_error {
   public:
    using std::runtime_error::runtime_error;
  };

  // Locks `file`, created if missing. Throws Busy ("FILE is locked by another process") when a
  // live process holds it, std::system_error naming the file for anything else. With
  // `remove_when_released`, the file goes when the lock does.
  explicit FileLock(std::filesystem::path file, bool remove_when_released = false);
  ~FileLock();
  FileLock(const FileLock&) = delete;
  FileLock& operator=(const FileLock&) = delete;

  // True when no live process holds `file`'s lock (a missing file: nobody does).
  static bool free(const std::filesystem::path& file);

 private:
  std::filesystem::path file_;
  bool remove_;
  int fd_ = -1;
};

}  // namespace hil
