// The io thread of the real `hilbench serve` never waits behind a request that parses or reads
// files (api_router.hpp Thread): a 700 KB campaign with 9 000 checks posted to /api/start while a
// campaign runs was parsed on it, and the abort sent after it was answered 22 s later. The parse
// is on the request worker now: abort and status are answered while it runs, before the post is.
#include <gtest/gtest.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <string>

#include "server_process.hpp"

namespace {

using namespace std::chrono_literals;
using hil::test::ServerProcess;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

// A campaign of `checks` checks (about 75 bytes each), the last one named as the first: the whole
// text is parsed and compiled before that is found, and the start is refused naming it.
std::string big_campaign(int checks) {
  std::string yaml = hil::test::short_campaign_yaml(5, "big") + "checks:\n";
  char line[128];
  for (int i = 0; i < checks; ++i) {
    std::snprintf(line, sizeof line, "  - {name: check_%06d, runs: [adaptive], metric: iae_mpa_s, max: %d.5}\n",
                  i + 1 == checks ? 0 : i, 1000 + i);
    yaml += line;
  }
  return yaml;
}

// Sends a whole request on a new connection; the socket, for reading the answer.
int send_request(int port, const std::string& request) {
  const int fd = hil::test::connect_loopback(port);
  if (fd < 0) return -1;
  for (std::size_t sent = 0; sent < request.size();) {
    const ssize_t n = ::send(fd, request.data() + sent, request.size() - sent, MSG_NOSIGNAL);
    if (n <= 0) return ::close(fd), -1;
    sent += static_cast<std::size_t>(n);
  }
  return fd;
}

// Waits for the answer's first bytes on `fd`; the status (0: none within `wait`).
int status_when_answered(int fd, std::chrono::milliseconds wait, std::string* body = nullptr) {
  pollfd p{fd, POLLIN, 0};
  if (::poll(&p, 1, static_cast<int>(wait.count())) != 1) return 0;
  std::string reply;
  char buf[65536];
  for (ssize_t n; (n = ::recv(fd, buf, sizeof buf, 0)) > 0;) reply.append(buf, static_cast<std::size_t>(n));
  if (body) *body = reply;
  return reply.rfind("HTTP/1.1 ", 0) == 0 && reply.size() >= 12 ? std::stoi(reply.substr(9, 3)) : -1;
}

std::string http_request(const std::string& method, const std::string& target, int port, const std::string& type,
                         const std::string& body) {
  return method + " " + target + " HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(port) + "\r\nContent-Type: " + type +
         "\r\nContent-Length: " + std::to_string(body.size()) + "\r\nConnection: close\r\n\r\n" + body;
}

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

}  // namespace

TEST(ServerIoThread, AbortAndStatusAreAnsweredWhileA9000CheckCampaignIsParsed) {
  ServerProcess server;
  const auto api = server.client();
  ASSERT_EQ(api.request("POST", "/api/start", hil::test::short_campaign_yaml(60), "application/yaml").status, 202);
  const json running = hil::test::wait_status(
      api, [](const json& s) { return hil::test::status_t(s) > 0.2; }, 30s);
  ASSERT_GT(hil::test::status_t(running), 0.2) << running.dump();

  const std::string yaml = big_campaign(9000);
  ASSERT_GT(yaml.size(), 650u * 1024);
  const auto t0 = Clock::now();
  const int post = send_request(server.port(), http_request("POST", "/api/start", server.port(), "application/yaml", yaml));
  ASSERT_GE(post, 0);
  const double post_sent_s = seconds_since(t0);
  // The operator's requests, sent once the big body is on its way.
  const int status = send_request(server.port(), http_request("GET", "/api/status", server.port(), "application/json", ""));
  const int abort = send_request(server.port(), http_request("POST", "/api/abort", server.port(), "application/json",
                                                             R"({"reason": "test: abort during a large start"})"));
  ASSERT_GE(status, 0);
  ASSERT_GE(abort, 0);
  const auto abort_sent = Clock::now();
  std::string abort_reply;
  const int abort_status = status_when_answered(abort, 20s, &abort_reply);
  const double abort_s = seconds_since(abort_sent);
  EXPECT_EQ(abort_status, 202) << abort_reply;
  EXPECT_EQ(status_when_answered(status, 20s), 200);
  // The big post is not answered yet: its parse is still running on the request worker.
  pollfd p{post, POLLIN, 0};
  const bool post_answered_first = ::poll(&p, 1, 0) == 1;
  std::string post_reply;
  const int post_status = status_when_answered(post, 60s, &post_reply);
  const double post_s = seconds_since(t0);
  ::close(post);
  ::close(status);
  ::close(abort);
  std::printf("post sent in %.1f ms, abort answered %.2f ms after it was sent, the post answered after %.0f ms\n",
              post_sent_s * 1e3, abort_s * 1e3, post_s * 1e3);
  EXPECT_FALSE(post_answered_first) << "the post was answered before the abort: abort waited behind it";
  // Generous for a loaded machine, and far below the 22 s it took on the io thread.
  EXPECT_LT(abort_s, 2.0);
  // The whole campaign was parsed: its last check's repeated name is named where it is.
  EXPECT_EQ(post_status, 400) << post_reply.substr(0, 2000);
  EXPECT_NE(post_reply.find("two checks have this name"), std::string::npos) << post_reply.substr(0, 2000);
  const json idle = hil::test::wait_status(
      api, [](const json& s) { return s["state"] == "idle"; }, 30s);
  EXPECT_EQ(idle["last"]["outcome"], "aborted") << idle.dump();
}

// A body larger than the io thread takes (kIoThreadBodyBytes) is parsed on the request worker, on
// every route: an abort with a 500 KB body is refused there, and the server goes on answering.
TEST(ServerIoThread, ALargeBodyOnAnIoThreadRouteIsReadOnTheWorker) {
  ServerProcess server;
  const auto api = server.client();
  const std::string reason(500 * 1024, 'x');
  const auto reply = api.post("/api/abort", {{"reason", reason}});
  EXPECT_EQ(reply.status, 400) << reply.body.substr(0, 300);
  EXPECT_NE(reply.body.find("'reason' must be one line of at most 500 bytes"), std::string::npos) << reply.body.substr(0, 300);
  EXPECT_EQ(api.get("/api/health").status, 200);
}
