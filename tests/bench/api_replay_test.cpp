// The API's answers, recorded: a fixed set of raw requests (every route of GET /api, good and
// bad: missing fields, wrong types, unknown fields, routes and query options, bad or no token, a
// foreign Host, oversize and malformed requests, WebSocket upgrades) sent to the real
// `hilbench serve`, each answer's status, Content-Type, Allow and Content-Disposition and its JSON
// body written down, and compared byte for byte with tests/bench/api_replay/recorded.txt. The
// recorded set was made before the server was split into its listener, session, router and
// resource files (issue 39), and holds the split to answering exactly as before.
//
// Normalised (truly variable, nothing else): the run's folder name (its UTC start time), the
// server's port, the source and temporary folders, the version, and the values named in a case's
// `vary` (JSON pointers: times, loop statistics, file sizes of a run that was aborted at a wall
// time). HTML bodies and a run's files are recorded by their first line only (the console page is
// another piece of work's; a run's files are the run's). To record again: HIL_API_REPLAY_RECORD=1 test_bench_api_replay.
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <unistd.h>

#include <fstream>
#include <sstream>

#include "server_process.hpp"

namespace {

using hil::test::ServerProcess;
using nlohmann::json;

constexpr const char* kToken = "replay-token-0123";

enum class Auth { good, none, bad, query };

struct Case {
  std::string method;
  std::string target;  // "{run}": the run's folder name
  std::string body = "";
  Auth auth = Auth::good;
  std::string content_type = "application/json";
  std::vector<std::string> vary = {};  // JSON pointers whose values vary from run to run
  std::string extra_headers = "";      // whole header lines
  std::string raw = "";                // when set: sent as it is ("{host}": the Host line)
};

std::string replace_all(std::string s, const std::string& from, const std::string& to) {
  if (from.empty()) return s;
  for (std::size_t at = 0; (at = s.find(from, at)) != std::string::npos; at += to.size()) s.replace(at, from.size(), to);
  return s;
}

std::string exchange(int port, const std::string& request) {
  const int fd = hil::test::connect_loopback(port);
  if (fd < 0) return "no connection";
  ::send(fd, request.data(), request.size(), MSG_NOSIGNAL);
  std::string reply;
  char buf[8192];
  for (ssize_t n; (n = ::recv(fd, buf, sizeof buf, 0)) > 0;) {
    reply.append(buf, static_cast<std::size_t>(n));
    if (reply.rfind("HTTP/1.1 101", 0) == 0 && reply.find("\r\n\r\n") != std::string::npos) break;
  }
  ::close(fd);
  return reply;
}

std::string header_value(const std::string& head, const std::string& name) {
  std::istringstream in(head);
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.size() > name.size() + 1 && strncasecmp(line.c_str(), name.c_str(), name.size()) == 0 && line[name.size()] == ':')
      return line.substr(name.size() + 2);
  }
  return "";
}

// One answer as recorded: its status line, the header fields that carry meaning, its body.
std::string record(const std::string& reply, const Case& c) {
  const auto end = reply.find("\r\n\r\n");
  if (end == std::string::npos) return "no answer: '" + reply.substr(0, 200) + "'\n";
  const std::string head = reply.substr(0, end);
  const std::string body = reply.substr(end + 4);
  std::string out = head.substr(0, head.find("\r\n")) + "\n";
  for (const char* name : {"Content-Type", "Allow", "Content-Disposition", "Cache-Control"}) {
    const std::string v = header_value(head, name);
    if (!v.empty()) out += std::string(name) + ": " + v + "\n";
  }
  // After a 101 come the stream's frames, as many as one read happened to take.
  if (body.empty() || out.rfind("HTTP/1.1 101", 0) == 0) return out;
  json j = json::parse(body, nullptr, false);
  // A file of a run (Content-Disposition: attachment) is the run's, not the API's: its first line.
  if (j.is_discarded() || header_value(head, "Content-Type") != "application/json" ||
      !header_value(head, "Content-Disposition").empty()) {
    return out + "first line: " + body.substr(0, body.find('\n')).substr(0, 120) + "\n";
  }
  for (const auto& pointer : c.vary) {
    const json::json_pointer p(pointer);
    if (j.contains(p)) j[p] = "<varies>";
  }
  if (j.contains("version")) j["version"] = "<version>";
  return out + j.dump(2, ' ', false, json::error_handler_t::replace) + "\n";
}

std::string request_text(const Case& c, int port, const std::string& run) {
  const std::string host = "Host: 127.0.0.1:" + std::to_string(port) + "\r\n";
  if (!c.raw.empty()) return replace_all(c.raw, "{host}", host);
  std::string target = replace_all(c.target, "{run}", run);
  std::string headers = host + c.extra_headers;
  if (c.auth == Auth::good) headers += std::string("Authorization: Bearer ") + kToken + "\r\n";
  if (c.auth == Auth::bad) headers += "Authorization: Bearer not-the-token\r\n";
  if (c.auth == Auth::query) target += std::string(target.find('?') == std::string::npos ? "?" : "&") + "token=" + kToken;
  if (!c.content_type.empty() && !c.body.empty()) headers += "Content-Type: " + c.content_type + "\r\n";
  return c.method + " " + target + " HTTP/1.1\r\n" + headers + "Content-Length: " + std::to_string(c.body.size()) +
         "\r\nConnection: close\r\n\r\n" + c.body;
}

const std::string kUpgrade =
    "Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n";

// Before any run: the routes that need none, and every refusal that does not depend on a run.
std::vector<Case> idle_cases() {
  const std::string big_header = "X-Filler: " + std::string(17 * 1024, 'x') + "\r\n";
  return {
      // authorisation
      {"GET", "/api/health", "", Auth::none},
      {"GET", "/api/health", "", Auth::bad},
      {"GET", "/", "", Auth::none},
      {"GET", "/api/health", "", Auth::query},
      {"GET", "/api/health"},
      {"GET", "/api/health?token=wrong-token-000", "", Auth::none},
      // the door: Host and Origin, the parser
      {"GET",
       "/api/health",
       "",
       Auth::good,
       "",
       {},
       "",
       "GET /api/health HTTP/1.1\r\nHost: evil.example\r\nConnection: close\r\n\r\n"},
      {"GET",
       "/api/health",
       "",
       Auth::good,
       "",
       {},
       "",
       "GET /api/health HTTP/1.1\r\n{host}Origin: http://evil.example\r\nConnection: close\r\n\r\n"},
      {"GET", "", "", Auth::good, "", {}, "", "NOT HTTP AT ALL\r\n\r\n"},
      {"GET", "", "", Auth::good, "", {}, "", "GET /api/health HTTP/1.1\r\n{host}" + big_header + "Connection: close\r\n\r\n"},
      {"POST",
       "",
       "",
       Auth::good,
       "",
       {},
       "",
       std::string("POST /api/start HTTP/1.1\r\n{host}Authorization: Bearer ") + kToken +
           "\r\nContent-Type: application/json\r\nContent-Length: 2000000\r\nConnection: close\r\n\r\n{}"},
      // routes, methods, query options
      {"GET", "/api"},
      {"GET", "/"},
      {"HEAD", "/api/health"},
      {"GET", "/favicon.ico"},
      {"GET", "/nope"},
      {"GET", "/api/nope"},
      {"GET", "/api/runs/a/b/c/d/e"},
      {"DELETE", "/api/status"},
      {"POST", "/api/runs"},
      {"PUT", "/api/runs/x/analyses"},
      {"GET", "/api/status?verbose=1"},
      {"GET", "/api/status?statu=1"},
      {"GET", "/api/status?token=a&token=b", "", Auth::none},
      {"GET", "/api/runs/x/events?offset=1&offset=2"},
      {"GET", "/api/campaigns", "", Auth::good, "", {}},
      {"GET", "/api/rigs"},
      {"GET", "/api/models"},
      {"GET", "/api/status"},
      {"GET", "/api/runs"},
      // WebSocket: the upgrade's refusals, the plain GET, a good upgrade
      {"GET", "/api/telemetry"},
      {"GET", "/api/telemetry?rate_hz=0", "", Auth::good, "", {}, kUpgrade},
      {"GET", "/api/telemetry?rate_hz=20abc", "", Auth::good, "", {}, kUpgrade},
      {"GET", "/api/telemetry?rate_hz=6000", "", Auth::good, "", {}, kUpgrade},
      {"GET", "/api/telemetry?rate=5", "", Auth::good, "", {}, kUpgrade},
      {"GET", "/api/status", "", Auth::good, "", {}, kUpgrade},
      {"GET", "/api/telemetry", "", Auth::none, "", {}, kUpgrade},
      {"GET",
       "/api/telemetry",
       "",
       Auth::good,
       "",
       {},
       "Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 13\r\n"},
      {"GET", "/api/telemetry?rate_hz=5", "", Auth::good, "", {}, kUpgrade},
      // POST /api/start: every way to get it wrong
      {"POST", "/api/start", "{not json"},
      {"POST", "/api/start", "[1, 2]"},
      {"POST", "/api/start", R"({"campaign": "a", "campaign": "b"})"},
      {"POST", "/api/start", R"({"campaing": "paper_fig6"})"},
      {"POST", "/api/start", "{}"},
      {"POST", "/api/start", ""},
      {"POST", "/api/start", R"({"campaign": 5})"},
      {"POST", "/api/start", R"({"campaign": "nope"})"},
      {"POST", "/api/start", R"({"campaign": "../rigs/sim"})"},
      {"POST", "/api/start", R"({"campaign": "paper_fig6", "rig": "nope"})"},
      {"POST", "/api/start", R"({"campaign": "paper_fig6", "rig": 3})"},
      {"POST", "/api/start", R"({"campaign": "paper_fig6", "campaign_yaml": "name: x"})"},
      {"POST", "/api/start", R"({"campaign_yaml": "name: x\nduration_s: [1\n"})"},
      {"POST", "/api/start", R"({"campaign_yaml": 7})"},
      {"POST", "/api/start", R"({"campaign": "paper_fig6", "runs": []})"},
      {"POST", "/api/start", R"({"campaign": "paper_fig6", "runs": ["a", "a"]})"},
      {"POST", "/api/start", R"({"campaign": "paper_fig6", "runs": "a"})"},
      {"POST", "/api/start", R"({"campaign": "paper_fig6", "runs": ["nope"]})"},
      {"POST", "/api/start", R"({"campaign": "paper_fig6", "speed": "fast"})"},
      {"POST", "/api/start", R"({"campaign": "paper_fig6", "speed": -1})"},
      {"POST", "/api/start?rig=sim", R"({"campaign": "paper_fig6"})"},
      {"POST", "/api/start?speed=abc", "name: x\n", Auth::good, "application/yaml"},
      {"POST", "/api/start?bogus=1", "name: x\n", Auth::good, "application/yaml"},
      {"POST", "/api/start?runs=", "name: x\n", Auth::good, "application/yaml"},
      {"POST", "/api/start", "name: x\nduration_s: [1\n", Auth::good, "application/yaml"},
      {"POST", "/api/start?rig=nope", "name: x\n", Auth::good, "application/yaml"},
      // control with nothing running
      {"POST", "/api/stop"},
      {"POST", "/api/abort", R"({"reason": "replay"})"},
      {"POST", "/api/abort", R"({"reason": "two\nlines"})"},
      {"POST", "/api/abort", R"({"reason": 5})"},
      {"POST", "/api/abort", R"({"why": "x"})"},
      {"POST", "/api/inject/gap", R"({"gap_deg": 0.5})"},
      {"POST", "/api/inject/gapp", "{}"},
      {"POST", "/api/inject/gap", R"({"gap_deg": "x"})"},
      {"POST", "/api/inject/gap", "{}"},
      {"POST", "/api/inject/gap", R"({"gap": 1})"},
      {"POST", "/api/inject/gap", R"({"programme": "yes"})"},
      {"POST", "/api/inject/sensor", R"({"mode": "x"})"},
      {"POST", "/api/inject/sensor", R"({"mode": "noise", "rms_kpa": -1})"},
      {"POST", "/api/inject/sensor", R"({"mode": "bias"})"},
      {"POST", "/api/inject/sensor", R"({"mode": "stuck", "duration_s": "long"})"},
      {"POST", "/api/inject/drive", R"({"mode": "spin"})"},
      {"POST", "/api/inject/drive", R"({"on": 1})"},
      {"POST", "/api/inject/rig", R"({"mode": "loud"})"},
      {"POST", "/api/inject/clear", R"({"x": 1})"},
      {"POST", "/api/inject/clear", "{}"},
      // run routes without the run
      {"GET", "/api/runs/nope"},
      {"GET", "/api/runs/nope/events"},
      {"GET", "/api/runs/nope/report.html"},
      {"GET", "/api/runs/nope/analyses"},
      {"POST", "/api/runs/nope/analyses", R"({"kind": "compare", "model": "nominal"})"},
      {"GET", "/api/runs/nope/analyses/a1"},
      {"GET", "/api/runs/nope/analyses/a1/report.html"},
      {"GET", "/api/runs/nope/telemetry.csv"},
      {"GET", "/api/runs/..%2F..%2Fetc/passwd"},
  };
}

// With a run going (started, refused a second time, injected into, aborted).
std::vector<Case> running_cases() {
  return {
      {"POST", "/api/start", R"({"campaign": "paper_fig6"})"},
      {"POST", "/api/inject/gap", R"({"gap_deg": 0.5})"},
      {"POST", "/api/inject/gap", R"({"gap_deg": 1000})"},
      {"POST", "/api/inject/sensor", R"({"mode": "bias", "bias_kpa": 5, "duration_s": 0.5})"},
      {"POST", "/api/inject/clear", "{}"},
      {"POST", "/api/abort", R"({"reason": "replay"})"},
  };
}

// The aborted run's folder.
std::vector<Case> run_cases() {
  return {
      {"GET", "/api/runs", "", Auth::good, "", {"/runs/0/start_utc", "/runs/0/stop_utc"}},
      {"GET", "/api/runs/{run}", "", Auth::good, "", {"/files", "/run"}},
      {"GET", "/api/runs/{run}/events?offset=abc"},
      {"GET", "/api/runs/{run}/events?offset=-1"},
      {"GET", "/api/runs/{run}/events?offset=1.5"},
      {"GET", "/api/runs/{run}/events?from=0"},
      {"GET", "/api/runs/{run}/run.json"},
      {"GET", "/api/runs/{run}/nope.csv"},
      {"GET", "/api/runs/{run}/report.html.tmp"},
      {"GET", "/api/runs/{run}/report.html?wait=2"},
      {"GET", "/api/runs/{run}/report.html?wiat=0"},
      {"GET", "/api/runs/{run}/analyses"},
      {"POST", "/api/runs/{run}/analyses", R"({"kind": "fit", "model": "nominal"})"},
      {"POST", "/api/runs/{run}/analyses", R"({"kind": "compar", "model": "nominal"})"},
      {"POST", "/api/runs/{run}/analyses", R"({"kind": "compare"})"},
      {"POST", "/api/runs/{run}/analyses", R"({"kind": "compare", "model": "nope"})"},
      {"POST", "/api/runs/{run}/analyses", R"({"kind": "compare", "model": 3})"},
      {"POST", "/api/runs/{run}/analyses", R"({"kind": "compare", "model": "nominal", "x": 1})"},
      {"POST", "/api/runs/{run}/analyses", "[]"},
      {"GET", "/api/runs/{run}/analyses/nope"},
      {"GET", "/api/runs/{run}/analyses/nope/report.html"},
  };
}

std::string replay() {
  ServerProcess server({}, kToken);
  const int port = server.port();
  const auto api = server.client();
  std::string out;
  std::string run = "no-run";
  auto play = [&](const std::vector<Case>& cases) {
    for (const auto& c : cases) {
      const std::string request = request_text(c, port, run);
      const std::string shown = c.raw.empty() ? c.method + " " + c.target : "raw: " + c.raw.substr(0, c.raw.find('\r'));
      out += "### " + shown + (c.auth == Auth::none ? " (no token)" : c.auth == Auth::bad ? " (wrong token)" : "");
      if (!c.body.empty()) out.append(" ").append(c.body, 0, 80);
      out += "\n";
      out += record(exchange(port, request), c) + "\n";
    }
  };
  play(idle_cases());
  // A run to abort: a subset of one run of the short campaign, slow enough to be running.
  const json start = {{"campaign_yaml", hil::test::short_campaign_yaml(30, "replay")}, {"runs", {"adaptive"}}, {"speed", 1}};
  std::vector<Case> started = {{"POST", "/api/start", start.dump(), Auth::good, "application/json", {"/status"}}};
  play(started);
  hil::test::wait_status(
      api, [](const json& s) { return s.value("state", "") == "running" && hil::test::status_t(s) > 0.2; },
      std::chrono::seconds(60));
  play(running_cases());
  hil::test::wait_status(
      api, [](const json& s) { return s.value("state", "") == "idle"; }, std::chrono::seconds(60));
  run = hil::test::only_run(server.runs_dir()).filename().string();
  play(run_cases());
  out = replace_all(out, run, "<run>");
  out = replace_all(out, server.dir().string(), "<tmp>");
  out = replace_all(out, hil::test::source_path("").string(), "<src>/");
  out = replace_all(out, std::to_string(port), "<port>");
  return out;
}

TEST(ApiReplay, EveryRouteAnswersAsRecorded) {
  const auto file = hil::test::source_path("tests/bench/api_replay/recorded.txt");
  const std::string now = replay();
  if (std::getenv("HIL_API_REPLAY_RECORD") != nullptr) {
    std::filesystem::create_directories(file.parent_path());
    std::ofstream(file, std::ios::binary) << now;
    GTEST_SKIP() << "recorded " << file;
  }
  const std::string before = hil::test::slurp(file);
  ASSERT_FALSE(before.empty()) << file << " is missing";
  // Case by case, so that a difference names its request.
  std::istringstream a(before), b(now);
  std::string la, lb, case_name;
  for (int line = 1;; ++line) {
    const bool more_a = static_cast<bool>(std::getline(a, la));
    const bool more_b = static_cast<bool>(std::getline(b, lb));
    if (!more_a && !more_b) break;
    if (la.rfind("### ", 0) == 0) case_name = la;
    ASSERT_EQ(la, lb) << "line " << line << " of " << file << ", in " << case_name;
    la.clear();
    lb.clear();
  }
  EXPECT_EQ(before, now);
}

}  // namespace
