#include "request_guard.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <set>

#include <boost/asio/ip/address.hpp>

#include "hil/json_file.hpp"
#include "hil/text_file.hpp"

namespace hil::bench {
namespace {

std::string lower(std::string_view v) {
  std::string out(v);
  std::transform(out.begin(), out.end(), out.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

bool host_char(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-' || c == '.' || c == '_';
}

// "[::1]" or "127.0.0.1": an IP literal (IPv6 in brackets).
bool ip_literal(const std::string& host) {
  boost::system::error_code ec;
  if (host.size() > 2 && host.front() == '[' && host.back() == ']') {
    const auto a = boost::asio::ip::make_address_v6(host.substr(1, host.size() - 2), ec);
    return !ec && !a.is_unspecified();
  }
  const auto a = boost::asio::ip::make_address_v4(host, ec);
  // make_address_v4 takes "1", "0x7f.1" (inet_aton forms) on some systems: only dotted quads.
  return !ec && std::count(host.begin(), host.end(), '.') == 3 && !a.is_unspecified();
}

struct Fd {
  int fd = -1;
  explicit Fd(int f) : fd(f) {}
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
  int release() {
    const int f = fd;
    fd = -1;
    return f;
  }
};

std::string shown(const std::filesystem::path& base, const std::vector<std::string>& parts, std::size_t upto) {
  std::filesystem::path p = base;
  for (std::size_t i = 0; i <= upto && i < parts.size(); ++i) p /= parts[i];
  return p.string();
}

// The parser's message without what it quotes of the text ("; last read: '...'"), which for a
// file may be the file's content and for a body is the client's own bytes.
std::string parse_reason(const nlohmann::json::parse_error& e) {
  std::string reason = e.what();
  const auto c = reason.find("column ");
  const auto colon = c == std::string::npos ? std::string::npos : reason.find(": ", c);
  if (colon != std::string::npos) reason = reason.substr(colon + 2);
  if (const auto quote = reason.find("; last read:"); quote != std::string::npos) reason.resize(quote);
  return reason;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Host and Origin.

std::optional<HostGuard::Authority> HostGuard::parse_authority(std::string_view text, unsigned default_port) {
  Authority a;
  std::string_view rest;
  if (!text.empty() && text.front() == '[') {
    const auto close = text.find(']');
    if (close == std::string_view::npos) return std::nullopt;
    a.host = lower(text.substr(0, close + 1));
    for (const char c : a.host.substr(1, a.host.size() - 2))
      if (!std::isxdigit(static_cast<unsigned char>(c)) && c != ':' && c != '.') return std::nullopt;
    rest = text.substr(close + 1);
  } else {
    const auto colon = text.find(':');
    a.host = lower(text.substr(0, colon));
    if (a.host.empty() || !std::all_of(a.host.begin(), a.host.end(), host_char)) return std::nullopt;
    rest = colon == std::string_view::npos ? std::string_view() : text.substr(colon);
  }
  if (rest.empty()) {
    a.port = default_port;
    return a;
  }
  if (rest.front() != ':' || rest.size() < 2 || rest.size() > 6) return std::nullopt;
  unsigned port = 0;
  for (const char c : rest.substr(1)) {
    if (c < '0' || c > '9') return std::nullopt;
    port = port * 10 + static_cast<unsigned>(c - '0');
  }
  if (port == 0 || port > 65535) return std::nullopt;
  a.port = port;
  return a;
}

HostGuard::HostGuard(const std::string& listen_address, unsigned short port, const std::vector<std::string>& allow)
    : port_(port) {
  boost::system::error_code ec;
  const auto address = boost::asio::ip::make_address(listen_address, ec);
  wildcard_ = !ec && address.is_unspecified();
  for (const char* name : {"127.0.0.1", "localhost", "[::1]"}) allowed_.push_back({name, port});
  if (!ec && !wildcard_) {
    allowed_.push_back({address.is_v6() ? "[" + lower(address.to_v6().to_string()) + "]" : address.to_string(), port});
  }
  if (wildcard_) {
    char name[256] = {};
    if (::gethostname(name, sizeof name - 1) == 0 && name[0] != '\0') {
      if (const auto a = parse_authority(name, port)) allowed_.push_back(*a);
    }
  }
  for (const auto& value : allow) {
    const auto a = parse_authority(value, port);
    if (!a) {
      throw std::invalid_argument("--allow-host '" + printable(value, 100) +
                                  "': give a host name or address, with :PORT when it is reached at another port "
                                  "(a proxy), e.g. bench.lab or bench.lab:443");
    }
    allowed_.push_back(*a);
  }
}

bool HostGuard::allowed(const Authority& a) const {
  if (std::any_of(allowed_.begin(), allowed_.end(), [&](const Authority& x) { return x.host == a.host && x.port == a.port; }))
    return true;
  return wildcard_ && a.port == port_ && ip_literal(a.host);
}

std::string HostGuard::names() const {
  std::string out;
  for (const auto& a : allowed_) out += (out.empty() ? "" : ", ") + a.host + ":" + std::to_string(a.port);
  if (wildcard_) out += ", any IP address of this machine:" + std::to_string(port_);
  return out;
}

std::optional<HeaderRefusal> HostGuard::check(std::string_view host, std::size_t host_count, std::string_view origin,
                                              std::size_t origin_count) const {
  const std::string why =
      "; this server answers " + names() +
      " (hilbench serve --allow-host NAME adds a name): a web page whose name was made to resolve to this machine "
      "(DNS rebinding) may neither drive the bench nor watch it";
  if (host_count == 0) {
    return HeaderRefusal{400, "Host header required", "the request carries no Host header" + why, "Host"};
  }
  if (host_count > 1) {
    return HeaderRefusal{400, "Host header given twice",
                         "the request carries " + std::to_string(host_count) + " Host headers; which one was meant?", "Host"};
  }
  const auto h = parse_authority(host, 80);
  if (!h || !allowed(*h)) {
    return HeaderRefusal{403, "foreign Host refused", "Host '" + printable(host, 200) + "' is not a name of this server" + why,
                         "Host"};
  }
  if (origin_count == 0) return std::nullopt;  // no browser: ctl, curl, scripts
  if (origin_count > 1) {
    return HeaderRefusal{403, "cross-origin request refused",
                         "the request carries " + std::to_string(origin_count) + " Origin headers", "Origin"};
  }
  std::optional<Authority> o;
  if (lower(origin.substr(0, 7)) == "http://") {
    o = parse_authority(origin.substr(7), 80);
  } else if (lower(origin.substr(0, 8)) == "https://") {
    o = parse_authority(origin.substr(8), 443);
  }
  if (!o || !allowed(*o)) {
    return HeaderRefusal{403, "cross-origin request refused",
                         "Origin '" + printable(origin, 200) +
                             "': the request came from a page of another site, not from this server's console; a page of "
                             "another site may not drive the bench" +
                             why,
                         "Origin"};
  }
  return std::nullopt;
}

// ---------------------------------------------------------------------------------------------
// JSON.

std::optional<std::size_t> too_deep(std::string_view text, std::size_t max_depth) {
  std::size_t depth = 0;
  bool in_string = false, escaped = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (escaped) {
        escaped = false;
      } else if (c == '\\') {
        escaped = true;
      } else if (c == '"') {
        in_string = false;
      }
      continue;
    }
    if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > max_depth) return i;
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
  return std::nullopt;
}

nlohmann::json parse_request_json(std::string_view text, std::size_t max_depth) {
  if (const auto at = too_deep(text, max_depth)) {
    throw JsonRefused("objects and arrays nested deeper than " + std::to_string(max_depth) + " levels (at byte " +
                      std::to_string(*at + 1) + ")");
  }
  // The keys of each object being parsed, innermost last: a key given twice is refused by name.
  std::vector<std::set<std::string>> keys;
  const nlohmann::json::parser_callback_t check = [&keys](int, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
    using E = nlohmann::json::parse_event_t;
    if (event == E::object_start) {
      keys.emplace_back();
    } else if (event == E::object_end) {
      if (!keys.empty()) keys.pop_back();
    } else if (event == E::key && !keys.empty() && parsed.is_string()) {
      const auto& key = parsed.get_ref<const std::string&>();
      if (!keys.back().insert(key).second) {
        const std::string name = printable(key, 100);
        throw JsonRefused("key '" + name + "' is given twice in one object; which one was meant?", name);
      }
    }
    return true;
  };
  try {
    return nlohmann::json::parse(text, check);
  } catch (const nlohmann::json::parse_error& e) {
    throw JsonRefused("parse error at " + json_error_position(text, e.byte) + ": " + parse_reason(e));
  } catch (const nlohmann::json::out_of_range&) {
    throw JsonRefused("a number is out of range (beyond a double)");
  } catch (const nlohmann::json::exception& e) {
    throw JsonRefused(std::string("not JSON: ") + e.what());
  }
}

OpenedFile open_inside(const std::filesystem::path& base, const std::vector<std::string>& parts, bool* missing) {
  if (missing != nullptr) *missing = false;
  Fd dir{::open(base.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC)};
  if (dir.fd < 0) {
    if (missing != nullptr && errno == ENOENT) {
      *missing = true;
      return {};
    }
    throw std::runtime_error(base.string() + ": cannot open the folder: " + std::strerror(errno));
  }
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const std::string& part = parts[i];
    if (part.empty() || part == "." || part == ".." || part.find('/') != std::string::npos)
      throw std::runtime_error(shown(base, parts, i) + ": not a plain name");
    const bool last = i + 1 == parts.size();
    const int flags = O_RDONLY | O_CLOEXEC | O_NOFOLLOW | (last ? O_NONBLOCK : O_DIRECTORY);
    Fd next{::openat(dir.fd, part.c_str(), flags)};
    if (next.fd < 0) {
      const int err = errno;
      if (err == ENOENT && missing != nullptr) {
        *missing = true;
        return {};
      }
      // O_NOFOLLOW: ELOOP for a link as the last part; O_DIRECTORY|O_NOFOLLOW: ENOTDIR for a link to a folder.
      struct stat st {};
      if (::fstatat(dir.fd, part.c_str(), &st, AT_SYMLINK_NOFOLLOW) == 0 && S_ISLNK(st.st_mode))
        throw std::runtime_error(shown(base, parts, i) + ": is a symbolic link (not followed: a run's files stay in its folder)");
      throw std::runtime_error(shown(base, parts, i) + ": cannot open: " + std::strerror(err));
    }
    if (last) {
      struct stat st {};
      if (::fstat(next.fd, &st) != 0) throw std::runtime_error(shown(base, parts, i) + ": cannot read: " + std::strerror(errno));
      if (!S_ISREG(st.st_mode)) throw std::runtime_error(shown(base, parts, i) + ": is not a regular file");
      // Reads block from here on: the O_NONBLOCK was for the open of a FIFO only.
      ::fcntl(next.fd, F_SETFL, ::fcntl(next.fd, F_GETFL) & ~O_NONBLOCK);
      return {next.release(), static_cast<std::uint64_t>(st.st_size)};
    }
    std::swap(dir.fd, next.fd);
  }
  throw std::runtime_error(base.string() + ": no file named");
}

std::string read_at(int fd, std::uint64_t offset, std::size_t max_bytes, const std::string& name) {
  std::string out(max_bytes, '\0');
  std::size_t got = 0;
  while (got < out.size()) {
    const ssize_t n = ::pread(fd, out.data() + got, out.size() - got, static_cast<off_t>(offset + got));
    if (n == 0) break;
    if (n < 0) {
      if (errno == EINTR) continue;
      throw std::runtime_error(name + ": cannot read: " + std::strerror(errno));
    }
    got += static_cast<std::size_t>(n);
  }
  out.resize(got);
  return out;
}

nlohmann::json read_json_inside(const std::filesystem::path& base, const std::vector<std::string>& parts, std::size_t max_bytes,
                                std::size_t max_depth) {
  const std::string name = shown(base, parts, parts.size());
  const OpenedFile opened = open_inside(base, parts);
  Fd in{opened.fd};
  if (opened.size > max_bytes)
    throw std::runtime_error(name + ": larger than " + std::to_string(max_bytes) + " bytes (" + std::to_string(opened.size) +
                             "): not read");
  std::string text;
  text.resize(static_cast<std::size_t>(opened.size));
  std::size_t got = 0;
  for (;;) {
    if (got == text.size()) text.resize(std::min(max_bytes + 1, text.size() + 4096));  // grew since fstat
    const ssize_t n = ::read(in.fd, text.data() + got, text.size() - got);
    if (n == 0) break;
    if (n < 0) {
      if (errno == EINTR) continue;
      throw std::runtime_error(name + ": cannot read: " + std::strerror(errno));
    }
    got += static_cast<std::size_t>(n);
    if (got > max_bytes) throw std::runtime_error(name + ": larger than " + std::to_string(max_bytes) + " bytes: not read");
  }
  text.resize(got);
  if (const auto at = too_deep(text, max_depth)) {
    throw std::runtime_error(name + ": objects and arrays nested deeper than " + std::to_string(max_depth) + " levels (at byte " +
                             std::to_string(*at + 1) + "): not parsed");
  }
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    throw std::runtime_error(name + ":" + json_error_position(text, e.byte) + ": not JSON: " + parse_reason(e));
  } catch (const nlohmann::json::exception&) {  // out_of_range: a number like 1e400
    throw std::runtime_error(name + ": not JSON: a number is out of range");
  }
}

bool resolves_inside(const std::filesystem::path& file, const std::filesystem::path& folder) {
  std::error_code ec, ec2;
  const auto f = std::filesystem::canonical(file, ec);
  const auto d = std::filesystem::canonical(folder, ec2);
  if (ec || ec2) return false;
  const auto rel = f.lexically_relative(d);
  return !rel.empty() && *rel.begin() != ".." && rel != ".";
}

RunRecord read_run_record_inside(const std::filesystem::path& dir) {
  return RunRecord::from_json(read_json_inside(dir.parent_path(), {dir.filename().string(), "run.json"}),
                              (dir / "run.json").string());
}

}  // namespace hil::bench
