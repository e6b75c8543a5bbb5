// Shared by the libFuzzer targets of tests/fuzz (see README.md there).
//
// A target feeds the input to a reader and must end in one of two ways: normally, or with one of
// the project's own error types carrying a message (a "clear error"). Anything else is a finding:
// a crash or sanitizer report (the build has ASan and UBSan, every report fatal), an exception of
// another type (reported here, then abort() so libFuzzer saves the input), a hang (-timeout) or
// runaway memory (-rss_limit_mb).
#pragma once

#include <signal.h>
#include <unistd.h>

#include <cerrno>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <typeinfo>

namespace hil::fuzz {

// Runs fn(); returns normally when it returns or throws one of Clear... with a non-empty message.
template <class... Clear, class Fn>
void expect_clear_errors(const char* what, Fn&& fn) {
  try {
    fn();
  } catch (const std::exception& e) {
    const bool clear = ((dynamic_cast<const Clear*>(&e) != nullptr) || ...);
    if (clear && e.what()[0] != '\0') return;
    std::fprintf(stderr, "\nFINDING in %s: %s exception of type %s: %s\n", what, clear ? "empty" : "unexpected", typeid(e).name(),
                 e.what());
    std::abort();
  } catch (...) {
    std::fprintf(stderr, "\nFINDING in %s: an exception not derived from std::exception\n", what);
    std::abort();
  }
}

// The readers under test take files: the input is written to one file per process (in /dev/shm
// when there is one, so a long campaign does not wear a disk), overwritten by every run.
class InputFile {
 public:
  explicit InputFile(std::string_view name) {
    std::error_code ec;
    std::filesystem::path dir = "/dev/shm";
    if (!std::filesystem::is_directory(dir, ec)) dir = std::filesystem::temp_directory_path();
    // libFuzzer ends without static destructors (a time limit, a finding): drop the folders of
    // earlier runs whose process is gone.
    for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
      const std::string n = e.path().filename().string();
      if (n.rfind("hilbench-fuzz-", 0) != 0) continue;
      const long pid = std::strtol(n.c_str() + 14, nullptr, 10);
      if (pid > 0 && ::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH) std::filesystem::remove_all(e.path(), ec);
    }
    dir /= "hilbench-fuzz-" + std::to_string(::getpid());
    std::filesystem::create_directories(dir);
    dir_ = dir;
    path_ = dir / name;
  }
  ~InputFile() {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;

  const std::filesystem::path& write(const std::uint8_t* data, std::size_t size) {
    std::ofstream out(path_, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    out.close();
    if (!out) {
      std::fprintf(stderr, "fuzz: cannot write %s\n", path_.c_str());
      std::abort();
    }
    return path_;
  }
  const std::filesystem::path& path() const { return path_; }
  const std::filesystem::path& dir() const { return dir_; }

 private:
  std::filesystem::path dir_, path_;
};

}  // namespace hil::fuzz
