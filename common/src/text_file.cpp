#include "hil/text_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <stdexcept>

namespace hil {

namespace {

// Closes the descriptor on every way out, the error paths included.
struct Fd {
  int fd;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

[[noreturn]] void fail(const std::filesystem::path& file, const std::string& what, int err) {
  throw std::runtime_error(file.string() + ": " + what + ": " + std::strerror(err));
}

}  // namespace

std::string read_text_file(const std::filesystem::path& file, std::string_view kind) {
  // O_NONBLOCK: opening a FIFO must not wait for a writer before fstat can refuse it.
  // A folder opens read-only on Linux: fstat below tells it apart.
  const Fd in{::open(file.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK)};
  if (in.fd < 0) fail(file, "cannot open the file", errno);
  struct stat st {};
  if (::fstat(in.fd, &st) != 0) fail(file, "cannot read the file", errno);
  if (S_ISDIR(st.st_mode)) throw std::runtime_error(file.string() + ": is a folder, not " + std::string(kind));
  if (!S_ISREG(st.st_mode)) throw std::runtime_error(file.string() + ": is not a regular file");
  std::string text;
  text.reserve(static_cast<std::size_t>(st.st_size));
  char chunk[65536];
  for (;;) {
    const ssize_t n = ::read(in.fd, chunk, sizeof chunk);
    if (n == 0) break;
    if (n < 0) {
      if (errno == EINTR) continue;
      fail(file, "cannot read the file", errno);
    }
    text.append(chunk, static_cast<std::size_t>(n));
  }
  return text;
}

std::string printable(std::string_view text, std::size_t max_bytes) {
  std::string out;
  for (std::size_t i = 0; i < text.size() && i < max_bytes; ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c < 0x20 || c == 0x7f) {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02x", c);
      out += hex;
    } else {
      out += static_cast<char>(c);
    }
  }
  if (text.size() > max_bytes) out += "...";
  return out;
}

}  // namespace hil
