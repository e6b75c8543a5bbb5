// The bench as a network service against a hostile web page and hostile files (issue 38): DNS
// rebinding (a foreign Host or Origin on every route and the WebSocket upgrade, with or without a
// token), symbolic links in run folders and among the plant models, a run.json nested 20 000 deep,
// request bodies nested deep or with a key twice, telemetry readers that outlive the idle timeout,
// and an abort answered with 1000 telemetry clients connected. Each reproduction of the issue ends
// in a clear error naming the header, field or file, never in file content echoed back.
#include <gtest/gtest.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <thread>

#include "run_command.hpp"
#include "run_folder.hpp"
#include "server_process.hpp"

namespace {

using namespace std::chrono_literals;
using hil::test::ServerProcess;
using nlohmann::json;

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// One raw exchange on its own connection (the request asks to close it, or is refused): the
// reply's status line, headers and body. An upgrade that succeeds ends the read at its header.
std::string raw_http(int port, const std::string& request) {
  const int fd = hil::test::connect_loopback(port);
  if (fd < 0) return "no connection";
  ::send(fd, request.data(), request.size(), MSG_NOSIGNAL);
  std::string reply;
  char buf[4096];
  for (ssize_t n; (n = ::recv(fd, buf, sizeof buf, 0)) > 0;) {
    reply.append(buf, static_cast<std::size_t>(n));
    if (reply.rfind("HTTP/1.1 101", 0) == 0 && has(reply, "\r\n\r\n")) break;
  }
  ::close(fd);
  return reply;
}

int status_of(const std::string& reply) {
  return reply.rfind("HTTP/1.1 ", 0) == 0 && reply.size() >= 12 ? std::stoi(reply.substr(9, 3)) : 0;
}

json body_of(const std::string& reply) {
  const auto end = reply.find("\r\n\r\n");
  return end == std::string::npos ? json() : json::parse(reply.substr(end + 4), nullptr, false);
}

// A request with the given header lines ("Name: value\r\n"), closing the connection.
std::string request(const std::string& method, const std::string& target, const std::string& headers,
                    const std::string& body = "") {
  return method + " " + target + " HTTP/1.1\r\n" + headers +
         "Content-Type: application/json\r\nContent-Length: " + std::to_string(body.size()) + "\r\nConnection: close\r\n\r\n" +
         body;
}

std::string upgrade(const std::string& headers, const std::string& extra = "") {
  return "GET /api/telemetry HTTP/1.1\r\n" + headers +
         "Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
         "Sec-WebSocket-Version: 13\r\n" +
         extra + "\r\n";
}

// The issue's reproduction and its like: a page whose name re-resolves to 127.0.0.1 sends its own
// name in Host and its own origin in Origin. Every route of GET /api and the telemetry upgrade
// refuse it 403 naming the header, with or without a token (a token does not make a foreign
// name this server's); the server's own names pass, with its port.
TEST(ServerGuard, AForeignHostOrOriginIsRefusedOnEveryRouteAndTheUpgrade) {
  ServerProcess server;
  const int port = server.port();
  const std::string own = "Host: 127.0.0.1:" + std::to_string(port) + "\r\n";
  const std::string evil_host = "Host: evil.example:" + std::to_string(port) + "\r\n";
  const std::string evil_origin = "Origin: http://evil.example:" + std::to_string(port) + "\r\n";

  // The issue: curl -H 'Host: evil.example:8470' -H 'Origin: http://evil.example:8470' .../api/start answered 202.
  const std::string started =
      raw_http(port, request("POST", "/api/start", evil_host + evil_origin, R"({"campaign":"paper_fig6"})"));
  EXPECT_EQ(status_of(started), 403) << started;
  EXPECT_EQ(body_of(started).value("field", ""), "Host") << started;
  EXPECT_TRUE(has(body_of(started).value("detail", ""), "evil.example")) << started;
  EXPECT_EQ(server.client().get("/api/status").json()["state"], "idle");

  const json endpoints = server.client().get("/api").json()["endpoints"];
  ASSERT_GE(endpoints.size(), 15u);
  std::size_t routes = 0;
  for (const auto& e : endpoints) {
    // "{name}" segments become "x" (built anew: GCC 12 warns falsely on replace() here, -Wrestrict).
    const std::string pattern = e["path"];
    std::string path;
    for (bool inside = false; const char c : pattern) {
      if (c == '{') {
        inside = true;
        path += 'x';
      } else if (c == '}') {
        inside = false;
      } else if (!inside) {
        path += c;
      }
    }
    const std::string method = e["method"];
    const std::string body = method == "POST" ? "{}" : "";
    for (const auto& [headers, header] :
         {std::pair{evil_host, "Host"}, std::pair{evil_host + evil_origin, "Host"}, std::pair{own + evil_origin, "Origin"},
          std::pair{own + "Origin: null\r\n", "Origin"}}) {
      const std::string reply = raw_http(port, request(method, path, headers, body));
      EXPECT_EQ(status_of(reply), 403) << method << " " << path << "\n" << headers << reply;
      EXPECT_EQ(body_of(reply).value("field", ""), header) << method << " " << path << "\n" << reply;
    }
    ++routes;
  }
  EXPECT_EQ(routes, endpoints.size());
  // The WebSocket upgrade, plain and Foxglove.
  for (const std::string& extra : {std::string(), std::string("Sec-WebSocket-Protocol: foxglove.websocket.v1\r\n")}) {
    EXPECT_EQ(status_of(raw_http(port, upgrade(evil_host, extra))), 403);
    EXPECT_EQ(status_of(raw_http(port, upgrade(own + evil_origin, extra))), 403);
    EXPECT_EQ(status_of(raw_http(port, upgrade(own, extra))), 101);
  }
  // Names that look like the server's but are not: no port (port 80), another port, a suffix, userinfo.
  for (const std::string& host : {std::string("127.0.0.1"), std::string("localhost"), std::string("127.0.0.1:1"),
                                  "127.0.0.1.evil.example:" + std::to_string(port), "evil@127.0.0.1:" + std::to_string(port),
                                  "127.0.0.1:" + std::to_string(port) + "@evil.example", std::string("")}) {
    const std::string reply = raw_http(port, request("GET", "/api/health", "Host: " + host + "\r\n"));
    EXPECT_EQ(status_of(reply), 403) << host << "\n" << reply;
  }
  for (const std::string& origin : {"http://127.0.0.1:" + std::to_string(port) + ".evil.example", std::string("http://127.0.0.1"),
                                    "file://127.0.0.1:" + std::to_string(port), std::string("http://localhost:1")}) {
    const std::string reply = raw_http(port, request("GET", "/api/health", own + "Origin: " + origin + "\r\n"));
    EXPECT_EQ(status_of(reply), 403) << origin << "\n" << reply;
  }
  // No Host, or two: 400 naming it.
  for (const std::string& headers : {std::string(), own + own}) {
    const std::string reply = raw_http(port, request("GET", "/api/health", headers));
    EXPECT_EQ(status_of(reply), 400) << reply;
    EXPECT_EQ(body_of(reply).value("field", ""), "Host") << reply;
  }
  // The server's own names, with its port, and the console's origin.
  for (const std::string& name :
       {std::string("127.0.0.1"), std::string("localhost"), std::string("LocalHost"), std::string("[::1]")}) {
    const std::string at = name + ":" + std::to_string(port);
    EXPECT_EQ(status_of(raw_http(port, request("GET", "/api/health", "Host: " + at + "\r\n"))), 200) << at;
    EXPECT_EQ(status_of(raw_http(port, request("GET", "/api/health", "Host: " + at + "\r\nOrigin: http://" + at + "\r\n"))), 200)
        << at;
  }
  EXPECT_TRUE(has(server.log(), "foreign Host refused")) << server.log();
}

TEST(ServerGuard, WithATokenAForeignHostIsStillRefusedAndAllowHostAddsANameAtThePort) {
  const std::string token = "right-token-123";
  ServerProcess server({"--allow-host", "bench.example", "--allow-host", "proxy.example:443"}, token);
  const int port = server.port();
  const std::string auth = "Authorization: Bearer " + token + "\r\n";
  const std::string evil = "Host: evil.example:" + std::to_string(port) + "\r\n";
  const std::string start = R"({"campaign":"paper_fig6"})";
  const std::string refused = raw_http(port, request("POST", "/api/start", evil + auth, start));
  EXPECT_EQ(status_of(refused), 403) << refused;
  EXPECT_EQ(body_of(refused).value("field", ""), "Host") << refused;
  EXPECT_EQ(status_of(raw_http(port, upgrade(evil + auth))), 403);
  EXPECT_EQ(status_of(raw_http(port, upgrade(evil, "Authorization: Bearer " + token + "\r\n"))), 403);

  const std::string named = "Host: bench.example:" + std::to_string(port) + "\r\n";
  EXPECT_EQ(status_of(raw_http(port, request("GET", "/api/health", named + auth))), 200);
  EXPECT_EQ(status_of(raw_http(port, request("GET", "/api/health", named))), 401);  // the name is no token
  EXPECT_EQ(status_of(raw_http(port, request("GET", "/api/health",
                                             named + "Origin: http://bench.example:" + std::to_string(port) + "\r\n" + auth))),
            200);
  EXPECT_EQ(status_of(raw_http(port, request("GET", "/api/health", "Host: bench.example:1\r\n" + auth))), 403);
  // NAME:PORT: that port only (a TLS proxy: no port in Host, https in Origin).
  EXPECT_EQ(status_of(raw_http(
                port, request("GET", "/api/health", "Host: proxy.example:443\r\nOrigin: https://proxy.example\r\n" + auth))),
            200);
  EXPECT_EQ(
      status_of(raw_http(port, request("GET", "/api/health", "Host: proxy.example:" + std::to_string(port) + "\r\n" + auth))),
      403);
  EXPECT_EQ(server.client().get("/api/status").json()["state"], "idle");

  // A value that is no host name stops the server before it listens, naming it.
  hil::test::TempDir dir;
  const auto r = hil::test::run_command(hil::test::hilbench_exe() + " serve --listen 127.0.0.1:0 --runs-dir " +
                                        (dir.path() / "runs").string() + " --configs " +
                                        hil::test::source_path("configs").string() + " --allow-host 'a b' 2>&1");
  EXPECT_NE(r.status, 0) << r.output;
  EXPECT_TRUE(has(r.output, "--allow-host 'a b'")) << r.output;
}

// A secret outside every folder of the bench, and the links a careless or hostile user makes to it.
struct Secret {
  explicit Secret(const std::filesystem::path& dir) : file(dir / "secret.txt") {
    std::ofstream(file) << "root:x:0:0:TOP-SECRET-LINE:/root:/bin/bash\n";
  }
  std::filesystem::path file;
};

void expect_no_secret(const std::string& text, const std::string& what) {
  EXPECT_FALSE(has(text, "TOP-SECRET")) << what << ": " << text;
  EXPECT_FALSE(has(text, "root:x")) << what << ": " << text;
}

// The issue: `ln -s /etc/passwd runs/R/events.jsonl` and GET /api/runs/R/events.jsonl served the
// file. No file of a run folder is followed through a link: not served, not listed, not parsed.
TEST(ServerGuard, LinksInARunFolderAreNeitherServedNorQuoted) {
  hil::test::TempDir base;
  const Secret secret(base.path());
  const auto runs = base.path() / "runs";
  const std::string yaml = hil::test::short_campaign_yaml(1);
  const auto campaign_file = hil::test::source_path("configs/campaigns/paper_adaptive.yaml");
  const std::string id = "20261127T050000Z_short_adaptive";
  hil::test::write_ended_run(runs / id, "short_adaptive", "adaptive", yaml, campaign_file, 1);
  std::ofstream(runs / id / "telemetry.csv") << "t_s,theta_cmd_deg,p_meas_mpa,theta_motor_deg,p_ref_mpa\n0,1,1,1,1\n";
  std::filesystem::create_symlink(secret.file, runs / id / "events.jsonl");
  std::filesystem::create_symlink(secret.file, runs / id / "notes.txt");
  // A run whose run.json is the link, and a run folder that is itself a link to a folder elsewhere.
  const std::string linked_json = "20261127T060000Z_short_adaptive";
  std::filesystem::create_directories(runs / linked_json);
  std::filesystem::create_symlink(secret.file, runs / linked_json / "run.json");
  const auto elsewhere = base.path() / "elsewhere";
  hil::test::write_ended_run(elsewhere, "short_adaptive", "adaptive", yaml, campaign_file, 1);
  std::filesystem::create_symlink(elsewhere, runs / "20261127T070000Z_short_adaptive");

  ServerProcess server({"--runs-dir", runs.string()});
  const auto api = server.client();
  for (const std::string file : {"events.jsonl", "notes.txt"}) {
    const auto reply = api.get("/api/runs/" + id + "/" + file);
    EXPECT_EQ(reply.status, 403) << file << ": " << reply.body;
    EXPECT_TRUE(has(reply.body, "symbolic link")) << reply.body;
    expect_no_secret(reply.body, file);
  }
  EXPECT_EQ(api.get("/api/runs/" + id + "/telemetry.csv").status, 200);
  const auto page = api.get("/api/runs/" + id);
  ASSERT_EQ(page.status, 200) << page.body;
  std::vector<std::string> listed;
  const json files = page.json()["files"];
  for (const auto& f : files) listed.push_back(f["name"]);
  EXPECT_EQ(std::count(listed.begin(), listed.end(), "events.jsonl"), 0) << page.body;
  EXPECT_EQ(std::count(listed.begin(), listed.end(), "telemetry.csv"), 1) << page.body;

  const auto linked = api.get("/api/runs/" + linked_json);
  EXPECT_EQ(linked.status, 422) << linked.body;
  EXPECT_TRUE(has(linked.body, "symbolic link")) << linked.body;
  expect_no_secret(linked.body, "run.json link");
  const auto list = api.get("/api/runs");
  expect_no_secret(list.body, "GET /api/runs");
  EXPECT_FALSE(has(list.body, "20261127T070000Z")) << list.body;  // the linked folder is no run
  EXPECT_EQ(api.get("/api/runs/20261127T070000Z_short_adaptive").status, 404);
  EXPECT_EQ(api.get("/api/runs/20261127T070000Z_short_adaptive/run.json").status, 404);
  // A report or an analysis would read the run's files: refused before it is queued.
  const auto report = api.get("/api/runs/" + id + "/report.html");
  EXPECT_EQ(report.status, 422) << report.body;
  expect_no_secret(report.body, "report");
  EXPECT_EQ(api.get("/api/health").status, 200);
}

// The issue: a model under configs/plant that is a link to /etc/shadow had its first line quoted
// in the analysis's failed.json and in GET /api/runs/ID/analyses. A model that resolves outside
// its folder is never read: GET /api/models says so without its content, an analysis against it
// is refused naming 'model', and a telemetry.csv that is a link is refused the same way.
TEST(ServerGuard, APlantModelThatLinksOutsideItsFolderIsNeverReadNorQuoted) {
  hil::test::TempDir base;
  const Secret secret(base.path());
  const auto configs = base.path() / "configs";
  std::filesystem::copy(hil::test::source_path("configs"), configs, std::filesystem::copy_options::recursive);
  std::filesystem::create_symlink(secret.file, configs / "plant" / "shadow.yaml");
  std::filesystem::create_symlink(secret.file, configs / "campaigns" / "shadow.yaml");
  std::filesystem::create_symlink(secret.file, configs / "rigs" / "shadow.yaml");
  const auto runs = base.path() / "runs";
  const std::string id = "20261127T050000Z_short_adaptive";
  hil::test::write_ended_run(runs / id, "short_adaptive", "adaptive", hil::test::short_campaign_yaml(1),
                             configs / "campaigns" / "paper_adaptive.yaml", 1);
  std::ofstream(runs / id / "telemetry.csv") << "t_s,theta_cmd_deg,p_meas_mpa,theta_motor_deg,p_ref_mpa\n0,1,1,1,1\n";
  const std::string linked_csv = "20261127T060000Z_short_adaptive";
  hil::test::write_ended_run(runs / linked_csv, "short_adaptive", "adaptive", hil::test::short_campaign_yaml(1),
                             configs / "campaigns" / "paper_adaptive.yaml", 1);
  std::filesystem::create_symlink(secret.file, runs / linked_csv / "telemetry.csv");

  ServerProcess server({"--configs", configs.string(), "--runs-dir", runs.string()});
  const auto api = server.client();
  const auto models = api.get("/api/models");
  expect_no_secret(models.body, "GET /api/models");
  EXPECT_TRUE(has(models.body, "shadow.yaml: a symbolic link to a file outside")) << models.body;
  const auto refused = api.post("/api/runs/" + id + "/analyses", {{"kind", "compare"}, {"model", "shadow"}});
  EXPECT_EQ(refused.status, 409) << refused.body;
  EXPECT_EQ(refused.json().value("field", ""), "model") << refused.body;
  expect_no_secret(refused.body, "POST analyses");
  const auto csv = api.post("/api/runs/" + linked_csv + "/analyses", {{"kind", "compare"}, {"model", "nominal"}});
  EXPECT_EQ(csv.status, 422) << csv.body;
  expect_no_secret(csv.body, "POST analyses of a linked telemetry.csv");
  for (const std::string& run : {id, linked_csv}) expect_no_secret(api.get("/api/runs/" + run + "/analyses").body, "analyses");
  // A campaign or rig file linked the same way: listed with the reason, refused at a start naming the field.
  for (const std::string list : {"/api/campaigns", "/api/rigs"}) {
    const auto listed = api.get(list);
    expect_no_secret(listed.body, list);
    EXPECT_TRUE(has(listed.body, "shadow.yaml: a symbolic link to a file outside")) << listed.body;
  }
  const auto campaign = api.post("/api/start", {{"campaign", "shadow"}});
  EXPECT_EQ(campaign.status, 409) << campaign.body;
  EXPECT_EQ(campaign.json().value("field", ""), "campaign") << campaign.body;
  expect_no_secret(campaign.body, "start shadow");
  const auto rig = api.post("/api/start", {{"campaign", "paper_fig6"}, {"rig", "shadow"}});
  EXPECT_EQ(rig.status, 409) << rig.body;
  EXPECT_EQ(rig.json().value("field", ""), "rig") << rig.body;
  expect_no_secret(rig.body, "start on rig shadow");
  EXPECT_EQ(api.get("/api/status").json()["state"], "idle");
  EXPECT_FALSE(std::filesystem::exists(runs / id / "analyses")) << "nothing was queued";
}

// The issue: a run.json nested 20 000 levels deep was pretty-printed on the thread that answers
// every request: status blocked 7 s, 800 MB. It is refused before it is parsed, naming the file
// and the limit, off the io thread; so is one too large, and a request body nested too deep.
TEST(ServerGuard, ARunJsonNestedDeepOrTooLargeIsRefusedBeforeItIsParsed) {
  hil::test::TempDir base;
  const auto runs = base.path() / "runs";
  const std::string deep = "20261127T050000Z_deep_adaptive", large = "20261127T060000Z_large_adaptive";
  std::filesystem::create_directories(runs / deep);
  std::filesystem::create_directories(runs / large);
  std::ofstream(runs / deep / "run.json") << "{\"campaign\": " << std::string(20000, '[') << std::string(20000, ']') << "}\n";
  {
    std::ofstream out(runs / large / "run.json");
    out << "{\"campaign\": \"";
    out << std::string(9u << 20, 'a');
    out << "\"}\n";
  }
  ServerProcess server({"--runs-dir", runs.string()});
  const auto api = server.client();
  const auto t0 = std::chrono::steady_clock::now();
  const auto page = api.get("/api/runs/" + deep);
  const double page_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(page.status, 422) << page.body.substr(0, 500);
  EXPECT_TRUE(has(page.body, "run.json: objects and arrays nested deeper than 64 levels")) << page.body.substr(0, 500);
  EXPECT_LT(page.body.size(), 2000u);
  EXPECT_LT(page_s, 5.0);  // 7 s and 800 MB before; generous for a busy machine
  const auto big = api.get("/api/runs/" + large);
  EXPECT_EQ(big.status, 422) << big.body.substr(0, 500);
  EXPECT_TRUE(has(big.body, "larger than 8388608 bytes")) << big.body.substr(0, 500);
  EXPECT_LT(big.body.size(), 2000u);
  const auto list = api.get("/api/runs");
  ASSERT_EQ(list.status, 200);
  EXPECT_EQ(list.json()["runs"].size(), 2u);
  EXPECT_LT(list.body.size(), 4000u);
  for (const auto& r : list.json()["runs"]) EXPECT_TRUE(r.contains("error")) << r.dump();
  EXPECT_EQ(api.get("/api/runs/" + deep + "/report.html").status, 422);
  EXPECT_EQ(api.get("/api/status").status, 200);

  // A request body: nested deeper than 32 levels, refused before it is parsed.
  const auto body = api.request("POST", "/api/abort", "{\"reason\": " + std::string(20000, '[') + std::string(20000, ']') + "}",
                                "application/json");
  EXPECT_EQ(body.status, 400) << body.body.substr(0, 500);
  EXPECT_TRUE(has(body.body, "nested deeper than 32 levels")) << body.body.substr(0, 500);
  EXPECT_LT(body.body.size(), 2000u);
}

// The issue: a key given twice in a request was accepted, the last one winning. Refused naming it.
TEST(ServerGuard, AKeyGivenTwiceInARequestIsRefusedNamingIt) {
  ServerProcess server;
  const auto api = server.client();
  struct Case {
    std::string target, body, key;
  };
  for (const Case& c : {Case{"/api/start", R"({"campaign": "paper_fig6", "campaign": "paper_adaptive"})", "campaign"},
                        Case{"/api/start", R"({"campaign": "paper_fig6", "speed": 1, "speed": 100})", "speed"},
                        Case{"/api/abort", R"({"reason": "a", "reason": "b"})", "reason"},
                        Case{"/api/inject/gap", R"({"gap_deg": 1, "gap_deg": 9})", "gap_deg"},
                        Case{"/api/runs/x/analyses", R"({"kind": "compare", "model": "a", "model": "b"})", "model"}}) {
    const auto reply = api.request("POST", c.target, c.body, "application/json");
    EXPECT_EQ(reply.status, 400) << c.target << " " << c.body << "\n" << reply.body;
    EXPECT_EQ(reply.json().value("field", ""), c.key) << reply.body;
    EXPECT_EQ(reply.json().value("error", ""), "duplicate key") << reply.body;
    EXPECT_TRUE(has(reply.json().value("detail", ""), "'" + c.key + "' is given twice")) << reply.body;
  }
  // The same key in two objects is no repeat (none of the API's bodies nests objects; the parser's rule).
  EXPECT_EQ(api.get("/api/status").json()["state"], "idle");
}

// Reads WebSocket frames from a raw connection: the opcodes seen until the server closes it (EOF
// or a close frame) or `limit` passes. Server frames are unmasked.
std::vector<int> frames_until_closed(int fd, std::chrono::milliseconds limit, bool* closed) {
  std::vector<int> opcodes;
  std::string pending;
  *closed = false;
  char head[1];
  while (pending.find("\r\n\r\n") == std::string::npos) {  // the 101's header, a byte at a time
    if (::recv(fd, head, 1, 0) != 1) {
      *closed = true;
      return opcodes;
    }
    pending.push_back(head[0]);
  }
  if (pending.rfind("HTTP/1.1 101", 0) != 0) {
    *closed = true;
    return opcodes;
  }
  pending.clear();
  const auto end = std::chrono::steady_clock::now() + limit;
  char buf[4096];
  while (std::chrono::steady_clock::now() < end) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 50) <= 0) continue;
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) {
      *closed = true;
      return opcodes;
    }
    pending.append(buf, static_cast<std::size_t>(n));
    for (;;) {
      if (pending.size() < 2) break;
      std::size_t size = static_cast<unsigned char>(pending[1]) & 0x7f, at = 2;
      if (size == 126) {
        if (pending.size() < 4) break;
        size = (static_cast<unsigned char>(pending[2]) << 8) | static_cast<unsigned char>(pending[3]);
        at = 4;
      } else if (size == 127) {
        if (pending.size() < 10) break;
        size = 0;
        for (int i = 0; i < 8; ++i) size = size << 8 | static_cast<unsigned char>(pending[2 + i]);
        at = 10;
      }
      if (pending.size() < at + size) break;
      const int opcode = static_cast<unsigned char>(pending[0]) & 0x0f;
      opcodes.push_back(opcode);
      pending.erase(0, at + size);
      if (opcode == 8) {
        *closed = true;
        return opcodes;
      }
    }
  }
  return opcodes;
}

// The issue: telemetry readers were cut at exactly 300 s: the idle timeout counted only what the
// client sent, and the server sent no ping. With the idle timeout shortened to 1 s, the server
// pings at half of it; a client that reads (and so answers pings, as every WebSocket client does)
// streams a 4 s run to its end, through four timeouts; one that is gone (answers nothing) is
// closed at the timeout.
TEST(ServerGuard, AReadingTelemetryClientOutlivesSeveralIdleTimeouts) {
  ServerProcess server({"--ws-idle-timeout-s", "1"});
  const int port = server.port();
  // A client that never answers: pinged, then closed.
  const int fd = hil::test::connect_loopback(port);
  ASSERT_GE(fd, 0);
  const std::string up = upgrade("Host: 127.0.0.1:" + std::to_string(port) + "\r\n");
  ASSERT_EQ(::send(fd, up.data(), up.size(), MSG_NOSIGNAL), static_cast<ssize_t>(up.size()));
  bool closed = false;
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<int> seen = frames_until_closed(fd, 15s, &closed);
  const double closed_after_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ::close(fd);
  EXPECT_NE(std::find(seen.begin(), seen.end(), 0x9), seen.end()) << "no ping frame from the server";
  EXPECT_TRUE(closed);
  EXPECT_GT(closed_after_s, 0.5);
  EXPECT_LT(closed_after_s, 10.0);

  // A reading client through a 4 s run.
  const auto api = server.client();
  ASSERT_EQ(api.post("/api/start", {{"campaign_yaml", hil::test::short_campaign_yaml(4)}, {"runs", {"adaptive"}}}).status, 202);
  std::size_t rows = 0;
  bool run_end = false;
  const auto s0 = std::chrono::steady_clock::now();
  api.stream("/api/telemetry?rate_hz=5", [&](const std::string& text) {
    const json m = json::parse(text);
    if (m.value("type", "") == "row") ++rows;
    if (m.value("type", "") == "run_end") run_end = true;
    return !run_end;
  });
  const double streamed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - s0).count();
  EXPECT_TRUE(run_end) << rows << " rows in " << streamed_s << " s, then the stream ended before the run did";
  EXPECT_GT(streamed_s, 3.0);
  EXPECT_GT(rows, 10u);
  hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "idle"; }, 20s);
}

// The issue: 256 telemetry streams took every connection, and POST /api/abort was closed at
// accept. Telemetry takes at most its share (256 streams; the other 744 get 503), so with 1000
// telemetry clients (plain and Foxglove) connected, an abort is answered, and fast (the issue
// asks 100 ms: best of three, each measured and printed), and the run ends in the safe state.
TEST(ServerGuard, AbortIsAnsweredWithAThousandTelemetryClientsConnected) {
  rlimit files{};
  ::getrlimit(RLIMIT_NOFILE, &files);
  if (files.rlim_cur < 1200 && files.rlim_max >= 1200) {
    files.rlim_cur = std::min<rlim_t>(files.rlim_max, 4096);
    ::setrlimit(RLIMIT_NOFILE, &files);
  }
  if (files.rlim_cur < 1200) GTEST_SKIP() << "needs 1200 file descriptors, the limit is " << files.rlim_cur;
  ServerProcess server;
  const int port = server.port();
  const auto api = server.client();
  ASSERT_EQ(api.post("/api/start", {{"campaign_yaml", hil::test::short_campaign_yaml(60)}, {"runs", {"adaptive"}}}).status, 202);
  hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "running"; }, 20s);
  std::vector<int> clients;
  const std::string host = "Host: 127.0.0.1:" + std::to_string(port) + "\r\n";
  for (int i = 0; i < 1000; ++i) {
    const int fd = hil::test::connect_loopback(port);
    ASSERT_GE(fd, 0) << i;
    const std::string up = upgrade(host, i % 2 == 0 ? "" : "Sec-WebSocket-Protocol: foxglove.websocket.v1\r\n");
    ::send(fd, up.data(), up.size(), MSG_NOSIGNAL);
    clients.push_back(fd);
  }
  // The server has taken its share of streams and refused the rest: each client's answer.
  int upgraded = 0, refused = 0;
  for (const int fd : clients) {
    std::string head;
    char c = 0;
    while (head.find("\r\n\r\n") == std::string::npos && ::recv(fd, &c, 1, 0) == 1) head.push_back(c);
    upgraded += status_of(head) == 101;
    refused += status_of(head) == 503;
  }
  EXPECT_EQ(upgraded, 256);
  EXPECT_EQ(refused, 744);
  EXPECT_TRUE(has(server.log(), "256 telemetry streams are open: refusing more (503)")) << server.log();
  std::vector<double> ms;
  for (int i = 0; i < 3; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    const auto reply = api.post("/api/abort", {{"reason", "1000 watchers"}});
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    EXPECT_EQ(reply.status, 202) << reply.body;
  }
  std::printf("abort with 1000 telemetry clients: %.1f, %.1f, %.1f ms\n", ms[0], ms[1], ms[2]);
  EXPECT_LT(*std::min_element(ms.begin(), ms.end()), 100.0);   // best of three: the issue's bound
  EXPECT_LT(*std::max_element(ms.begin(), ms.end()), 2000.0);  // none waits for the streams (5 s before)
  const json s = hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "idle"; }, 30s);
  EXPECT_EQ(s["last"]["outcome"], "aborted") << s.dump(2);
  EXPECT_EQ(s["last"]["reason"], "operator abort: 1000 watchers") << s.dump(2);
  for (const int fd : clients) ::close(fd);
}

}  // namespace
