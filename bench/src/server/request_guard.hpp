// What every request to `hilbench serve` passes before any route sees it, and how the server reads
// JSON it did not make itself in memory (a request body) or reads back from a run folder.
//
// Host and Origin (DNS rebinding): a web page whose name an attacker makes resolve to 127.0.0.1
// reaches a loopback server with its own name in Host, and its own origin in Origin. The server
// answers only the names it is known by: its listen address, the loopback names (127.0.0.1,
// localhost, [::1]), each with the port it listens on, and the names given with --allow-host
// (NAME: at the server's port; NAME:PORT: at that port, for a proxy). A listen address that is a
// wildcard (0.0.0.0, ::) also answers any IP literal at its port and the machine's host name: an
// IP literal cannot be re-resolved. Checked on every route and on the WebSocket upgrade, with or
// without a token; a foreign Host or Origin is refused 403 naming the header.
//
// JSON: a body is bounded in size by the HTTP parser (--max-body-kb); its nesting is bounded here
// before it is parsed, and a key given twice in one object is refused naming it (the last one won
// before, silently). A JSON file of a run folder is opened without following a symbolic link,
// bounded in size and nesting before it is parsed, and a parse error never quotes the file.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "hil/bench/rt/run_record.hpp"

namespace hil::bench {

// A refusal of a request's Host or Origin: the status (403 foreign, 400 missing or given twice),
// the error, the detail and the header at fault.
struct HeaderRefusal {
  int status;
  std::string error, detail, header;
};

class HostGuard {
 public:
  // listen_address: the address the server is bound to (an IP literal, IPv6 without brackets);
  // port: the port it listens on (the bound one when 0 was asked for); allow: --allow-host
  // values, NAME or NAME:PORT. Throws std::invalid_argument naming a value that is no host name.
  HostGuard(const std::string& listen_address, unsigned short port, const std::vector<std::string>& allow);

  // host_count / origin_count: how many Host / Origin fields the request carries.
  std::optional<HeaderRefusal> check(std::string_view host, std::size_t host_count, std::string_view origin,
                                     std::size_t origin_count) const;

  // "127.0.0.1:8470, localhost:8470, [::1]:8470, ...": what the server answers to, for errors and the log.
  std::string names() const;

 private:
  struct Authority {
    std::string host;  // lower case; IPv6 in brackets
    unsigned port = 0;
  };
  // Splits "host[:port]" (default_port when no port is given); nullopt when it is no authority.
  static std::optional<Authority> parse_authority(std::string_view text, unsigned default_port);
  bool allowed(const Authority& a) const;

  unsigned port_;
  bool wildcard_ = false;
  std::vector<Authority> allowed_;
};

// A JSON text refused before or while it is parsed: `what` is the message, `field` the key at
// fault where one is (a key given twice).
struct JsonRefused : std::runtime_error {
  JsonRefused(const std::string& what, std::string field_ = "") : std::runtime_error(what), field(std::move(field_)) {}
  std::string field;
};

inline constexpr std::size_t kMaxRequestJsonDepth = 32;     // a request's body: objects and arrays nested at most this deep
inline constexpr std::size_t kMaxFileJsonDepth = 64;        // run.json, analysis.json, failed.json
inline constexpr std::size_t kMaxFileJsonBytes = 8u << 20;  // the same files (a run.json is a few kB)

// Where the text nests objects and arrays deeper than max_depth: the byte offset of the bracket
// too deep, or nullopt. A scan without allocation, before any parser sees the text.
std::optional<std::size_t> too_deep(std::string_view text, std::size_t max_depth);

// A request body's JSON: nesting bounded (kMaxRequestJsonDepth), a key twice in one object
// refused naming it. Throws JsonRefused (the parser's message without the text it quotes).
nlohmann::json parse_request_json(std::string_view text, std::size_t max_depth = kMaxRequestJsonDepth);

// A JSON file of a run folder: `parts` (plain names) below `base`, each opened without following
// a symbolic link (O_NOFOLLOW), the last one a regular file of at most max_bytes, nested at most
// max_depth. Throws std::runtime_error naming the file as "base/part/...": "FILE: is a symbolic
// link", "FILE:LINE:COLUMN: not JSON: REASON" (never a quote of the text), "FILE: larger than N
// bytes", "FILE: nested deeper than N levels".
nlohmann::json read_json_inside(const std::filesystem::path& base, const std::vector<std::string>& parts,
                                std::size_t max_bytes = kMaxFileJsonBytes, std::size_t max_depth = kMaxFileJsonDepth);

// A run folder's run.json as a record (read_json_inside: no link followed, bounded in size and
// nesting before it is parsed; a run.json nested 20 000 deep held the server 7 s and 800 MB).
RunRecord read_run_record_inside(const std::filesystem::path& dir);

// A file below `base` opened for reading: the one way the server opens a file of a run folder
// (run.json, events.jsonl, telemetry.csv, reports, analyses, the file route, the interrupted-run
// scan). Each part is opened without following a symbolic link (O_NOFOLLOW; the folders
// O_DIRECTORY), the last one O_NONBLOCK so that a FIFO cannot hold the open, and it must be a
// regular file (fstat after the open: a FIFO, a device or a socket is refused). A regular file's
// read never waits for a writer, so the caller's bounded read (read_at) is its time bound too.
// Returns the descriptor (the caller owns it) and its size. Throws std::runtime_error naming the
// file as above, without its content; `missing` is set instead of throwing when a part does not
// exist (ENOENT), and -1 returned.
struct OpenedFile {
  int fd = -1;
  std::uint64_t size = 0;
};
OpenedFile open_inside(const std::filesystem::path& base, const std::vector<std::string>& parts, bool* missing = nullptr);

// At most max_bytes of an open file from byte `offset` (fewer at its end). Throws
// std::runtime_error naming `name` when the read fails.
std::string read_at(int fd, std::uint64_t offset, std::size_t max_bytes, const std::string& name);

// Whether `file` resolves (symbolic links followed) to a path inside `folder` (which is resolved
// too). False when either does not exist.
bool resolves_inside(const std::filesystem::path& file, const std::filesystem::path& folder);

}  // namespace hil::bench
