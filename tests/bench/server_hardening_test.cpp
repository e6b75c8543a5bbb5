// The real `hilbench serve` against careless and hostile use: malformed requests mid-run, a
// posted campaign reaching for files outside the bench, a disk that fills during a run, a server
// killed with -9, tokens and logs, a second abort, a WebSocket reader too slow for the stream.
// Every case ends in a clear answer, the safe state where a run was under way, and records that
// say what happened.
#include <gtest/gtest.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <fstream>
#include <thread>

#include "hil/mcap.hpp"
#include "hil/telemetry_schema.hpp"
#include "run_command.hpp"
#include "server_process.hpp"
#include "small_disk.hpp"

namespace {

using namespace std::chrono_literals;
using hil::test::ServerProcess;
using nlohmann::json;

std::string campaign_request(double duration_s, const std::string& name = "short_adaptive", double speed = 1,
                             const std::string& runs = "adaptive") {
  return json{{"campaign_yaml", hil::test::short_campaign_yaml(duration_s, name)}, {"runs", {runs}}, {"speed", speed}}.dump();
}

// Starts campaign_request(duration_s) and waits until its run is past t_s simulated seconds;
// false when it did not start or did not get there within `timeout`.
bool start_and_reach(const hil::bench::ApiClient& api, double duration_s, double t_s, std::chrono::seconds timeout) {
  if (api.request("POST", "/api/start", campaign_request(duration_s), "application/json").status != 202) return false;
  const json s = hil::test::wait_status(
      api, [t_s](const json& x) { return hil::test::status_t(x) > t_s; }, timeout);
  return hil::test::status_t(s) > t_s;
}

// A raw request's "Host: 127.0.0.1" with the server's port: the server answers its own names
// with its port only (a Host without one is port 80's, and refused as foreign).
std::string with_port(std::string request, int port) {
  const std::string bare = "Host: 127.0.0.1\r\n";
  for (auto at = request.find(bare); at != std::string::npos; at = request.find(bare, at + 1))
    request.replace(at, bare.size(), "Host: 127.0.0.1:" + std::to_string(port) + "\r\n");
  return request;
}

// The port a connected socket's peer listens on.
int peer_port(int fd) {
  sockaddr_in addr{};
  socklen_t len = sizeof addr;
  if (::getpeername(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0) return 0;
  return ntohs(addr.sin_port);
}

bool ends_with_newline(const std::filesystem::path& file) {
  const std::string text = hil::test::slurp(file);
  return !text.empty() && text.back() == '\n';
}

std::size_t data_rows(const std::filesystem::path& csv) {
  std::ifstream in(csv);
  std::size_t rows = 0;
  bool header = false;
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    if (!header) {
      header = true;
    } else {
      ++rows;
    }
  }
  return rows;
}

TEST(ServerHardening, MalformedRequestsMidRunGetAnAnswerAndTheRunGoesOn) {
  ServerProcess server;
  const auto api = server.client();
  ASSERT_TRUE(start_and_reach(api, 3, 0.3, 20s));

  struct Bad {
    std::string method, target, body;
    int status;
  };
  const Bad bad[] = {
      {"POST", "/api/start", "{\"campaign\": \"\xff\xfe\"}", 400},  // invalid UTF-8 in a string value
      {"POST", "/api/start", "{\"\xff\": 1}", 400},                 // ... in a key
      {"POST", "/api/start", "{\"campaign\": \"x\", \"speed\": 1e400}", 400},
      {"GET", "/api/runs?runs=%ff", "", 400},  // an unknown query key is refused, naming it
      {"GET", "/api/runs/%ff", "", 404},
      {"GET", "/api/runs/%ff/%fe", "", 404},
      {"GET", "/api/\xff\xfe", "", 404},                      // raw bytes in the path
      {"POST", "/api/abort", "{\"reason\": \"\xc3\"}", 400},  // truncated UTF-8
      {"POST", "/api/inject/\xff", "{}", 404},
  };
  for (const auto& b : bad) {
    const auto reply = api.request(b.method, b.target, b.body, "application/json");
    EXPECT_EQ(reply.status, b.status) << b.target << " " << reply.body;
    EXPECT_NO_THROW((void)reply.json()) << reply.body;  // always a JSON answer
  }
  EXPECT_EQ(api.get("/api/health").status, 200);
  const json s = hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "idle"; }, 30s);
  EXPECT_EQ(s["last"]["outcome"], "completed") << s.dump(2);
  const auto run = json::parse(hil::test::slurp(hil::test::only_run(server.runs_dir()) / "run.json"));
  EXPECT_EQ(run["telemetry"]["rows_written"], 3000);
}

TEST(ServerHardening, APostedCampaignCannotReadFilesOutsideTheBench) {
  ServerProcess server;
  const auto api = server.client();
  const auto secret = server.dir() / "secret.yaml";
  std::ofstream(secret) << "TOP-SECRET-LINE: do not show\n";
  for (const std::string& plant : {secret.string(), std::string("/etc/shadow"), std::string("../../../../../../etc/passwd")}) {
    std::string yaml = hil::test::short_campaign_yaml(1);
    yaml.replace(yaml.find("../plant/nominal.yaml"), std::string("../plant/nominal.yaml").size(), plant);
    const auto reply = api.post("/api/start", {{"campaign_yaml", yaml}});
    EXPECT_EQ(reply.status, 400) << reply.body;
    EXPECT_NE(reply.body.find("may only name a plant file inside"), std::string::npos) << reply.body;
    for (const char* leak : {"TOP-SECRET", "root:", "do not show"})
      EXPECT_EQ(reply.body.find(leak), std::string::npos) << reply.body;
  }
  // A plant path that is a folder is the client's mistake: 400, not 500.
  std::string yaml = hil::test::short_campaign_yaml(1);
  yaml.replace(yaml.find("../plant/nominal.yaml"), std::string("../plant/nominal.yaml").size(), "../plant");
  const auto folder = api.post("/api/start", {{"campaign_yaml", yaml}});
  EXPECT_EQ(folder.status, 400) << folder.body;
  EXPECT_NE(folder.body.find("is a folder"), std::string::npos) << folder.body;
  EXPECT_EQ(api.get("/api/status").json()["state"], "idle");
}

TEST(ServerHardening, AFullDiskIsATripAndTheRecordStaysHonest) {
  hil::test::TempDir base;
  hil::test::SmallDisk disk(base.path() / "runs", "24m");  // room for 20 s of telemetry.csv and telemetry.mcap
  if (!disk.mounted()) GTEST_SKIP() << "cannot mount a tmpfs here (not root?): the full-disk case needs its own small disk";
  ServerProcess server({"--runs-dir", (base.path() / "runs").string()});
  const auto api = server.client();

  // A campaign whose record cannot fit is refused before it starts.
  const auto too_big = api.request("POST", "/api/start", campaign_request(600, "ten_minutes"), "application/json");
  EXPECT_EQ(too_big.status, 507) << too_big.body;
  EXPECT_NE(too_big.body.find("MB free"), std::string::npos) << too_big.body;

  // The disk fills up while a run is under way: the loop trips to its safe state and ends.
  ASSERT_TRUE(start_and_reach(api, 20, 1.0, 30s));
  disk.fill();
  const json s = hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "idle"; }, 30s);
  ASSERT_EQ(s["state"], "idle") << s.dump(2);
  EXPECT_EQ(s["last"]["outcome"], "aborted") << s.dump(2);
  const std::string reason = s["last"]["reason"];
  EXPECT_NE(reason.find("recording: telemetry could not be recorded"), std::string::npos) << reason;
  EXPECT_NE(reason.find("No space left on device"), std::string::npos) << reason;
  EXPECT_NE(reason.find("rows not recorded"), std::string::npos) << reason;

  std::filesystem::path dir;
  for (const auto& e : std::filesystem::directory_iterator(base.path() / "runs")) {
    if (e.is_directory()) dir = e.path();
  }
  ASSERT_FALSE(dir.empty());
  const json run = json::parse(hil::test::slurp(dir / "run.json"));
  EXPECT_EQ(run["outcome"], "aborted");
  EXPECT_EQ(run["trip"]["reason"], "recording");
  EXPECT_FALSE(std::filesystem::exists(dir / ".run.json.tmp"));
  EXPECT_FALSE(std::filesystem::exists(dir / ".reserve"));
  // What is on disk ends on a whole line, and the counts add up to the periods the loop ran.
  EXPECT_TRUE(ends_with_newline(dir / "telemetry.csv"));
  EXPECT_TRUE(ends_with_newline(dir / "events.jsonl"));
  const std::size_t rows = data_rows(dir / "telemetry.csv");
  EXPECT_EQ(run["telemetry"]["rows_written"], rows);
  EXPECT_GT(run["telemetry"]["rows_unwritten"].get<std::size_t>(), 0u);
  EXPECT_EQ(rows + run["telemetry"]["rows_unwritten"].get<std::size_t>() + run["telemetry"]["rows_lost"].get<std::size_t>(),
            run["periods_run"].get<std::size_t>());
  EXPECT_LT(rows, 20000u);

  // A start on a disk that is still full is refused, not accepted and then lost.
  const auto on_full = api.request("POST", "/api/start", campaign_request(1), "application/json");
  EXPECT_EQ(on_full.status, 507) << on_full.body;
  disk.unfill();
  EXPECT_EQ(api.request("POST", "/api/start", campaign_request(1), "application/json").status, 202);
  EXPECT_EQ(hil::test::wait_status(
                api, [](const json& x) { return x["state"] == "idle"; }, 30s)["last"]["outcome"],
            "completed");
}

TEST(ServerHardening, ARunWhoseServerWasKilledIsMarkedInterruptedWithTheRowsOnDisk) {
  hil::test::TempDir base;
  const auto runs = base.path() / "runs";
  {
    ServerProcess first({"--runs-dir", runs.string()});
    const auto api = first.client();
    ASSERT_TRUE(start_and_reach(api, 60, 1.0, 30s));
    ASSERT_EQ(::kill(first.pid(), SIGKILL), 0);
    ASSERT_TRUE(hil::test::wait_exit(first.pid(), 10s).has_value());
  }
  const auto dir = hil::test::only_run(runs);
  EXPECT_EQ(json::parse(hil::test::slurp(dir / "run.json"))["outcome"], "running");  // the lie a crash leaves

  ServerProcess second({"--runs-dir", runs.string()});
  const auto listed = second.client().get("/api/runs").json()["runs"];
  ASSERT_EQ(listed.size(), 1u) << listed.dump(2);
  EXPECT_EQ(listed[0]["outcome"], "interrupted");
  const json run = json::parse(hil::test::slurp(dir / "run.json"));
  EXPECT_EQ(run["outcome"], "interrupted");
  EXPECT_NE(run["reason"].get<std::string>().find("ended during the run"), std::string::npos);
  EXPECT_TRUE(ends_with_newline(dir / "telemetry.csv"));
  const std::size_t rows = data_rows(dir / "telemetry.csv");
  EXPECT_GT(rows, 500u);
  EXPECT_EQ(run["telemetry"]["rows_written"], rows);
  EXPECT_EQ(run["telemetry"]["rows_expected"], 60000);
  const auto events = hil::test::read_jsonl(dir / "events.jsonl");
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.back()["kind"], "interrupted");
  EXPECT_NE(second.log().find("marked interrupted"), std::string::npos);
  // telemetry.mcap finished: it ends in a footer and the magic, and holds the messages of its
  // whole chunks (the rows the CSV has, flushed with it), which run.json counts.
  hil::mcap::Reader mcap(dir / "telemetry.mcap");
  hil::mcap::Message m;
  std::size_t messages = 0, telemetry = 0;
  while (mcap.next(m)) ++messages, telemetry += mcap.channels().at(m.channel_id).topic == hil::telemetry::kTopic;
  EXPECT_FALSE(mcap.truncated());
  const std::string bytes = hil::test::slurp(dir / "telemetry.mcap");
  EXPECT_EQ(bytes.substr(bytes.size() - 8), std::string("\x89MCAP0\r\n", 8));
  EXPECT_EQ(run["interrupted"]["telemetry.mcap"]["messages"], messages) << run["interrupted"].dump();
  EXPECT_GT(telemetry, rows / 2);
  EXPECT_LE(telemetry, rows);
}

TEST(ServerHardening, TokensMustBeRealAndNeverReachTheLog) {
  hil::test::TempDir dir;
  for (const char* blank : {"   ", "short", "has space inside"}) {
    const pid_t pid =
        hil::test::spawn({hil::test::hilbench_exe(), "serve", "--listen", "127.0.0.1:0", "--token", blank, "--configs",
                          hil::test::source_path("configs").string(), "--runs-dir", (dir.path() / "runs").string()},
                         dir.path() / "log");
    const auto rc = hil::test::wait_exit(pid, 10s);
    ASSERT_TRUE(rc.has_value());
    EXPECT_EQ(*rc, 1) << blank;
  }
  EXPECT_NE(hil::test::slurp(dir.path() / "log").find("the token must be printable ASCII without spaces"), std::string::npos);

  ServerProcess server({}, "right-token-123");
  const auto anonymous = server.client("");
  EXPECT_EQ(anonymous.get("/api/status?token=%20").status, 401);
  EXPECT_EQ(anonymous.get("/api/status?token=wrong-token-456").status, 401);
  EXPECT_EQ(anonymous.get("/api/status?token=right-token-123").status, 200);
  const auto not_found = anonymous.get("/api/nothing?a=1&token=right-token-123");  // logged: an error
  EXPECT_EQ(not_found.status, 404);
  const auto wrong_method = anonymous.request("DELETE", "/api/status?token=right-token-123", "", "application/json");
  EXPECT_EQ(wrong_method.status, 405);
  for (const auto* reply : {&not_found, &wrong_method}) {  // the error's detail names the target, not the secret
    EXPECT_EQ(reply->body.find("right-token-123"), std::string::npos) << reply->body;
    EXPECT_NE(reply->body.find("token=<redacted>"), std::string::npos) << reply->body;
  }
  const std::string log = server.log();
  EXPECT_EQ(log.find("wrong-token-456"), std::string::npos) << log;
  EXPECT_EQ(log.find("right-token-123"), std::string::npos) << log;
  EXPECT_NE(log.find("token=<redacted>"), std::string::npos) << log;
}

// Runs a 3 s campaign on `server` and makes the run's folder immutable while it runs (no new
// file in it, while the open telemetry and event files still take lines), so that its final
// run.json cannot be written; returns the run's folder once the campaign has ended, still
// immutable. Empty when chattr +i does not work here.
std::filesystem::path run_whose_final_record_fails(ServerProcess& server, const std::filesystem::path& runs) {
  const auto api = server.client();
  EXPECT_EQ(api.request("POST", "/api/start", campaign_request(3, "short_adaptive", 1, "adaptive"), "application/json").status,
            202);
  hil::test::wait_status(
      api, [](const json& s) { return hil::test::status_t(s) > 0.5; }, 30s);
  const auto dir = hil::test::only_run(runs);
  if (std::system(("chattr +i " + dir.string() + " 2>/dev/null").c_str()) != 0) return {};
  const json s = hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "idle"; }, 30s);
  EXPECT_EQ(s["last"]["outcome"], "completed");
  EXPECT_NE(server.log().find("cannot write the final run.json"), std::string::npos);
  return dir;
}

// Such a run keeps its end in events.jsonl, and the next server restores that outcome instead of
// calling the run interrupted by a crash.
TEST(ServerHardening, ARunWhoseFinalRecordWasNotWrittenIsRestoredNotCalledInterrupted) {
  hil::test::TempDir base;
  const auto runs = base.path() / "runs";
  std::filesystem::path dir;
  {
    ServerProcess first({"--runs-dir", runs.string()});
    dir = run_whose_final_record_fails(first, runs);
    if (dir.empty()) GTEST_SKIP() << "chattr +i does not work here (not root, or not ext2/3/4/xfs)";
    ASSERT_EQ(std::system(("chattr -i " + dir.string()).c_str()), 0);
  }
  EXPECT_EQ(json::parse(hil::test::slurp(dir / "run.json"))["outcome"], "running");
  EXPECT_EQ(hil::test::read_jsonl(dir / "events.jsonl").back()["kind"], "final_record_unwritten");

  ServerProcess second({"--runs-dir", runs.string()});
  const json run = json::parse(hil::test::slurp(dir / "run.json"));
  EXPECT_EQ(run["outcome"], "completed") << run.dump(2);
  EXPECT_NE(run["reason"].get<std::string>().find("its final run.json could not be written"), std::string::npos);
  EXPECT_EQ(run["telemetry"]["rows_written"], 3000);
}

// A second server on the same runs folder (a second terminal, a service started twice) cleaned at
// its start what it took for a dead server's leftovers: the live server's half-made analyses
// (which then failed "cannot write ... No such file or directory"), and marked runs. It is now
// refused before it touches anything; the first server goes on.
TEST(ServerHardening, ASecondServerOnTheSameRunsFolderIsRefusedAndTouchesNothing) {
  hil::test::TempDir base;
  const auto runs = base.path() / "runs";
  ServerProcess first({"--runs-dir", runs.string()});
  const auto half_made = runs / "20261129T090000Z_paper_adaptive_none/analyses/.a7.tmp";  // the first server's, in the making
  std::filesystem::create_directories(half_made);
  std::ofstream(half_made / "diagnosis.json") << "{}\n";
  std::string refusal;
  try {
    ServerProcess second({"--runs-dir", runs.string()});
  } catch (const std::runtime_error& e) {
    refusal = e.what();
  }
  EXPECT_NE(refusal.find("another hilbench serve uses the runs folder " + runs.string()), std::string::npos) << refusal;
  EXPECT_TRUE(std::filesystem::exists(half_made / "diagnosis.json"));
  EXPECT_EQ(first.client().get("/api/health").status, 200);
}

// The live server does not list such a run as running while the file says so: it shows the end
// it keeps, refuses a review (which reads the file) with a 409 that says why, and writes the file
// as soon as the disk takes it again.
TEST(ServerHardening, TheLiveServerShowsTheEndOfARunWhoseFinalRecordWasNotWritten) {
  hil::test::TempDir base;
  const auto runs = base.path() / "runs";
  ServerProcess server({"--runs-dir", runs.string()});
  const auto dir = run_whose_final_record_fails(server, runs);
  if (dir.empty()) GTEST_SKIP() << "chattr +i does not work here (not root, or not ext2/3/4/xfs)";
  const std::string id = dir.filename().string();
  const auto api = server.client();

  const auto listed = api.get("/api/runs").json()["runs"];
  const auto one = api.get("/api/runs/" + id).json()["run"];
  const auto review = api.get("/api/runs/" + id + "/report.html");
  ASSERT_EQ(std::system(("chattr -i " + dir.string()).c_str()), 0);
  ASSERT_EQ(listed.size(), 1u);
  EXPECT_EQ(listed[0]["outcome"], "completed") << listed.dump(2);
  EXPECT_NE(listed[0]["reason"].get<std::string>().find("final run.json could not be written"), std::string::npos);
  EXPECT_EQ(one["outcome"], "completed") << one.dump(2);
  EXPECT_EQ(review.status, 409) << review.body;
  EXPECT_NE(review.body.find("final run.json could not be written"), std::string::npos) << review.body;
  EXPECT_EQ(json::parse(hil::test::slurp(dir / "run.json"))["outcome"], "running");

  // The folder takes files again: the next request writes the record, and it is the file's now.
  EXPECT_EQ(api.get("/api/runs").json()["runs"][0]["outcome"], "completed");
  const json run = json::parse(hil::test::slurp(dir / "run.json"));
  EXPECT_EQ(run["outcome"], "completed") << run.dump(2);
  EXPECT_EQ(run["telemetry"]["rows_written"], 3000);
  const int status = api.get("/api/runs/" + id + "/report.html").status;
  EXPECT_TRUE(status == 200 || status == 202) << status;  // made now, or queued as a job
}

// Idle connections by the hundred (a flood took 20 000 descriptors and the next run.json could
// not be written): past 320 open ones the server closes the longest idle one for each newcomer,
// keeps its descriptors, and the operator is answered while the flood is still open (before, the
// flood locked everyone out until it closed or the 60 s idle timeout ended it).
TEST(ServerHardening, AConnectionFloodIsCappedAndTheOperatorIsStillAnswered) {
  ServerProcess server;
  const auto open_fds = [&] {
    return static_cast<int>(std::distance(std::filesystem::directory_iterator("/proc/" + std::to_string(server.pid()) + "/fd"),
                                          std::filesystem::directory_iterator{}));
  };
  const int before = open_fds();
  std::vector<int> sockets;
  for (int i = 0; i < 400; ++i) {
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    ASSERT_GE(fd, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<std::uint16_t>(server.port()));
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr), 0);
    sockets.push_back(fd);
  }
  // The server takes the flood in as it comes: wait until it has seen the cap.
  for (int i = 0; i < 200 && server.log().find("closing the longest idle one") == std::string::npos; ++i) {
    std::this_thread::sleep_for(50ms);
  }
  EXPECT_NE(server.log().find("320 connections are open: closing the longest idle one for each new one"), std::string::npos)
      << server.log();
  const auto api = server.client();
  EXPECT_EQ(api.get("/api/health").status, 200);  // the flood is still open
  EXPECT_EQ(api.get("/api/status").status, 200);
  EXPECT_LE(open_fds() - before, 320 + 8);  // the cap, and a few of the server's own
  // The oldest of the flood were the ones closed: their peer sees the end of the stream.
  const timeval wait_s{30, 0};  // a failure, not a hang, if it stayed open
  ::setsockopt(sockets.front(), SOL_SOCKET, SO_RCVTIMEO, &wait_s, sizeof wait_s);
  char byte = 0;
  EXPECT_EQ(::recv(sockets.front(), &byte, 1, 0), 0);
  for (const int fd : sockets) ::close(fd);
}

// Watchers never cost the record: 250 WebSocket clients at 5000 rows/s that never read, during
// a 20 s run at 10 kHz on a busy machine. The recorder thread used to post every row to every session itself; it
// fell behind the loop, the ring filled, and the run was aborted with 2002 rows lost (a tester's
// run). Now the hub's own thread fans out, and what it cannot stream is the stream's loss only.
TEST(ServerHardening, WatchersThatNeverReadDoNotCostTheRunAnyRow) {
  hil::test::TempDir base;
  const auto runs = base.path() / "runs";
  ServerProcess server({"--runs-dir", runs.string()});
  std::vector<int> watchers;
  const std::string upgrade = with_port(
      "GET /api/telemetry?rate_hz=5000 HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
      "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n",
      server.port());
  for (int i = 0; i < 250; ++i) {
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    ASSERT_GE(fd, 0);
    const int small = 4096;  // the server's sends stall at once
    ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<std::uint16_t>(server.port()));
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr), 0);
    ASSERT_EQ(::send(fd, upgrade.data(), upgrade.size(), MSG_NOSIGNAL), static_cast<ssize_t>(upgrade.size()));
    watchers.push_back(fd);
  }
  std::string yaml = hil::test::short_campaign_yaml(20, "watched");
  yaml.replace(yaml.find("period_ms: 1\n"), 13, "period_ms: 0.1\n");
  const auto api = server.client();
  ASSERT_EQ(
      api.request("POST", "/api/start", json{{"campaign_yaml", yaml}, {"runs", {"adaptive"}}}.dump(), "application/json").status,
      202);
  // A busy machine, as a bench PC running other work is: two threads that want a core each.
  std::atomic<bool> busy{true};
  std::vector<std::thread> load;
  for (int i = 0; i < 2; ++i)
    load.emplace_back([&busy] {
      for (volatile std::uint64_t n = 0; busy.load(std::memory_order_relaxed);) n = n + 1;
    });
  const json s = hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "idle"; }, 180s);
  busy = false;
  for (auto& t : load) t.join();
  for (const int fd : watchers) ::close(fd);
  EXPECT_EQ(s["last"]["outcome"], "completed") << s.dump(2);
  const json run = json::parse(hil::test::slurp(hil::test::only_run(runs) / "run.json"));
  EXPECT_EQ(run["outcome"], "completed") << run.dump(2);
  EXPECT_EQ(run["telemetry"]["rows_lost"], 0) << run.dump(2);
  EXPECT_EQ(run["telemetry"]["rows_written"], 200000) << run.dump(2);
}

// One raw HTTP exchange on its own connection (the request must ask to close it): the reply's
// status line and headers, and its body.
std::string raw_exchange(int port, const std::string& request_for_host) {
  const int fd = hil::test::connect_loopback(port);
  if (fd < 0) return "no connection";
  const std::string request = with_port(request_for_host, port);
  ::send(fd, request.data(), request.size(), MSG_NOSIGNAL);
  std::string reply;
  char buf[4096];
  for (ssize_t n; (n = ::recv(fd, buf, sizeof buf, 0)) > 0;) {
    reply.append(buf, static_cast<std::size_t>(n));
    if (reply.find("HTTP/1.1 101") == 0 && reply.find("\r\n\r\n") != std::string::npos) break;  // a WebSocket now
  }
  ::close(fd);
  return reply;
}

// A page of another web site open in the operator's browser may neither drive the bench nor
// watch its stream: a tester's page injected a gap change into a running campaign (a no-cors
// text/plain POST) and read 20 rows of telemetry. Requests carrying a foreign Origin get 403; the
// console's own (Origin = the Host it was served from) and clients without an Origin go on.
TEST(ServerHardening, APageOfAnotherSiteCannotDriveTheBenchNorWatchIt) {
  ServerProcess server;
  const std::string host = "127.0.0.1:" + std::to_string(server.port());
  const auto inject = [&](const std::string& origin) {
    const std::string body = R"({"gap_deg": 1.0})";
    return raw_exchange(server.port(), "POST /api/inject/gap HTTP/1.1\r\nHost: " + host + "\r\n" + origin +
                                           "Content-Type: text/plain\r\nContent-Length: " + std::to_string(body.size()) +
                                           "\r\nConnection: close\r\n\r\n" + body);
  };
  const auto watch = [&](const std::string& origin) {
    return raw_exchange(server.port(), "GET /api/telemetry HTTP/1.1\r\nHost: " + host + "\r\n" + origin +
                                           "Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: "
                                           "dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n");
  };
  for (const std::string& foreign : std::vector<std::string>{"Origin: http://evil.example\r\n", "Origin: null\r\n",
                                                             "Origin: http://" + host + ".evil.example\r\n"}) {
    const std::string posted = inject(foreign), upgraded = watch(foreign);
    EXPECT_EQ(posted.rfind("HTTP/1.1 403", 0), 0u) << foreign << posted;
    EXPECT_NE(posted.find("cross-origin request refused"), std::string::npos) << posted;
    EXPECT_EQ(upgraded.rfind("HTTP/1.1 403", 0), 0u) << foreign << upgraded;
  }
  // The console's own origin, and no Origin at all (ctl, curl): served (409: nothing runs).
  for (const std::string& own : {"Origin: http://" + host + "\r\n", std::string()}) {
    EXPECT_EQ(inject(own).rfind("HTTP/1.1 409", 0), 0u) << own;
    EXPECT_EQ(watch(own).rfind("HTTP/1.1 101", 0), 0u) << own;
  }
}

// ctl against something that is no hilbench server: what it sends reaches the terminal with its
// control bytes shown, not obeyed; JSON of the wrong shape is said to be so; a reply announcing
// more than 64 MiB is refused, not allocated.
TEST(ServerHardening, CtlAgainstAPeerThatIsNoHilbenchServer) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"HTTP/1.1 500 Oops\r\nContent-Type: application/json\r\nContent-Length: 47\r\nConnection: close\r\n\r\n"
       "{\"error\": \"boom\", \"detail\": \"\\u001b[2Jgone\"}   ",
       "boom: \\x1b[2Jgone (HTTP 500)"},
      {"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nContent-Length: 16\r\nConnection: close\r\n\r\n"
       "{\"state\": 12345}",
       "answered with JSON that is not a hilbench server's reply"},
      {"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nContent-Length: 99999999999\r\nConnection: close\r\n\r\n{",
       "body limit exceeded"},
  };
  for (const auto& [reply, expected] : cases) {
    const int listener = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    ASSERT_GE(listener, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(::bind(listener, reinterpret_cast<const sockaddr*>(&addr), sizeof addr), 0);
    ASSERT_EQ(::listen(listener, 4), 0);
    socklen_t len = sizeof addr;
    ASSERT_EQ(::getsockname(listener, reinterpret_cast<sockaddr*>(&addr), &len), 0);
    std::thread peer([listener, text = reply] {
      const int c = ::accept(listener, nullptr, nullptr);
      if (c < 0) return;
      char request[4096];
      (void)::recv(c, request, sizeof request, 0);
      (void)::send(c, text.data(), text.size(), MSG_NOSIGNAL);
      ::shutdown(c, SHUT_WR);
      std::this_thread::sleep_for(200ms);
      ::close(c);
    });
    const auto r = hil::test::run_command("timeout 30 " + hil::test::hilbench_exe() +
                                          " ctl --server http://127.0.0.1:" + std::to_string(ntohs(addr.sin_port)) + " status");
    peer.join();
    ::close(listener);
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_NE(r.output.find(expected), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find('\x1b'), std::string::npos) << r.output;
  }
}

TEST(ServerHardening, ASecondAbortAnswersWithTheReasonTheRunEndsWith) {
  ServerProcess server;
  const auto api = server.client();
  ASSERT_TRUE(start_and_reach(api, 30, 0.2, 20s));
  const auto first = api.post("/api/abort", {{"reason", "first"}}).json();
  const auto second = api.post("/api/abort", {{"reason", "second"}}).json();
  EXPECT_EQ(first["reason"], "operator abort: first");
  EXPECT_EQ(second["reason"], "operator abort: first");
  EXPECT_TRUE(second.contains("note"));
  const json s = hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "idle"; }, 20s);
  EXPECT_EQ(s["last"]["reason"], "operator abort: first");
}

// An abort's reason went as it was into the server log: a newline in it forged a log line of its
// own, an escape sequence drove the terminal of whoever read the log. A reason with a control
// character, or longer than 500 bytes, is refused naming 'reason', and the run goes on until a
// sound abort ends it with that one's reason.
TEST(ServerHardening, AnAbortReasonThatWouldForgeLogLinesIsRefused) {
  ServerProcess server;
  const auto api = server.client();
  ASSERT_TRUE(start_and_reach(api, 30, 0.2, 20s));
  for (const std::string& reason :
       {std::string("x\n[2026-11-28 01:00:00.000] [info] FORGED campaign started"), std::string("red \x1b[31m"),
        std::string("csi \xc2\x9b"
                    "31m"),
        std::string(501, 'r')}) {
    const auto refused = api.post("/api/abort", {{"reason", reason}});
    EXPECT_EQ(refused.status, 400) << refused.body;
    EXPECT_EQ(refused.json().value("field", ""), "reason") << refused.body;
  }
  EXPECT_EQ(api.get("/api/status").json()["state"], "running");
  ASSERT_EQ(api.post("/api/abort", {{"reason", "a plain reason, d\u00e9j\u00e0 vu"}}).status, 202);
  const json s = hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "idle"; }, 20s);
  EXPECT_EQ(s["last"]["reason"], "operator abort: a plain reason, d\u00e9j\u00e0 vu");
  const std::string log = server.log();
  EXPECT_EQ(log.find("\n[2026-11-28 01:00:00.000] [info] FORGED"), std::string::npos) << log;
  EXPECT_EQ(log.find('\x1b'), std::string::npos) << log;
}

// A stop or abort sent right after the start (before the first run began, or between runs) is
// answered 202, so the campaign must end stopped or aborted with the reason, never "completed"
// with its runs skipped. Which window a request hits depends on timing; each try must hold.
TEST(ServerHardening, AStopOrAbortRightAfterTheStartIsTheCampaignsOutcome) {
  ServerProcess server;
  const auto api = server.client();
  for (int i = 0; i < 6; ++i) {
    const bool abort = i % 2 == 0;
    ASSERT_EQ(api.request("POST", "/api/start", campaign_request(30), "application/json").status, 202);
    const auto reply = abort ? api.post("/api/abort", {{"reason", "at once"}}) : api.post("/api/stop", json::object());
    ASSERT_EQ(reply.status, 202) << reply.body;
    const json s = hil::test::wait_status(
        api, [](const json& x) { return x["state"] == "idle"; }, 30s);
    EXPECT_EQ(s["last"]["outcome"], abort ? "aborted" : "stopped") << s.dump();
    if (abort) {
      EXPECT_EQ(s["last"]["reason"], "operator abort: at once") << s.dump();
    }
  }
}

TEST(ServerHardening, ASlowWebSocketReaderIsToldInBandWhatItMissed) {
  ServerProcess server;
  const auto api = server.client();
  ASSERT_EQ(api.request("POST", "/api/start", campaign_request(200, "fast", 20), "application/json").status, 202);
  bool stalled = false;
  json dropped;
  std::size_t rows = 0;
  api.stream("/api/telemetry?rate_hz=5000", [&](const std::string& text) {
    const json m = json::parse(text);
    if (m["type"] == "row") ++rows;
    if (!stalled && m["type"] == "row") {
      stalled = true;
      std::this_thread::sleep_for(4s);  // a reader that stops reading: the server's queue fills
    }
    if (m["type"] == "dropped") {
      dropped = m;
      return false;
    }
    return true;
  });
  ASSERT_FALSE(dropped.is_null()) << rows << " rows and no 'dropped' notice";
  EXPECT_GT(dropped["messages"].get<long>(), 0);
  EXPECT_GE(dropped["total"].get<long>(), dropped["messages"].get<long>());
  EXPECT_NE(dropped["why"].get<std::string>().find("telemetry.csv is the lossless record"), std::string::npos);
  api.post("/api/abort", {{"reason", "test done"}});
  hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "idle"; }, 20s);
}

}  // namespace

// A run.json cut short (a disk that failed under it, a hand edit) is an answer naming the file,
// line and column, never a 500: the run's own page says 422, the list shows the run with the
// error, and a report or analysis of it is refused the same way.
TEST(ServerHardening, ACutRunJsonIsNamedWithItsLineAndColumnNeverA500) {
  ServerProcess server;
  const auto api = server.client();
  const auto dir = server.runs_dir() / "20261127T050000Z_cut_adaptive";
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "run.json") << "{\n  \"campaign\": \"cut\",\n  \"run\": \"adaptive\",\n  \"outcome\": ";
  std::ofstream(dir / "telemetry.csv") << "t_s,theta_cmd_deg,p_meas_mpa,theta_motor_deg,p_ref_mpa\n0,1,1,1,1\n";

  const auto page = api.get("/api/runs/20261127T050000Z_cut_adaptive");
  EXPECT_EQ(page.status, 422) << page.body;
  EXPECT_NE(page.json().value("detail", "").find("run.json:4:14: not JSON: "), std::string::npos) << page.body;
  const json list = api.get("/api/runs").json();
  ASSERT_EQ(list["runs"].size(), 1u) << list.dump();
  EXPECT_NE(list["runs"][0].value("error", "").find("run.json:4:14: not JSON: "), std::string::npos) << list.dump();
  const auto report = api.get("/api/runs/20261127T050000Z_cut_adaptive/report.html");
  EXPECT_EQ(report.status, 422) << report.body;
  const auto analysis = api.post("/api/runs/20261127T050000Z_cut_adaptive/analyses", {{"kind", "compare"}, {"model", "nominal"}});
  EXPECT_EQ(analysis.status, 422) << analysis.body;
  EXPECT_EQ(api.get("/api/health").status, 200);
}

// A run.json that is a FIFO (or a device) is refused at once: read as a file it blocked the
// server's I/O thread in open(), so every later request, health included, hung until SIGTERM.
TEST(ServerHardening, ARunJsonThatIsAFifoIsRefusedAndTheServerKeepsAnswering) {
  ServerProcess server;
  const auto api = server.client();
  const auto dir = server.runs_dir() / "20261127T050000Z_fifo_adaptive";
  std::filesystem::create_directories(dir);
  ASSERT_EQ(::mkfifo((dir / "run.json").c_str(), 0600), 0);

  const auto page = api.get("/api/runs/20261127T050000Z_fifo_adaptive");
  EXPECT_EQ(page.status, 422) << page.body;
  EXPECT_NE(page.json().value("detail", "").find("run.json: is not a regular file"), std::string::npos) << page.body;
  const auto report = api.get("/api/runs/20261127T050000Z_fifo_adaptive/report.html");
  EXPECT_EQ(report.status, 422) << report.body;
  EXPECT_EQ(api.get("/api/runs").status, 200);
  EXPECT_EQ(api.get("/api/health").status, 200);
}

// ---------------------------------------------------------------------------------------------
// The HTTP and WebSocket protocol against a hostile client, on raw sockets: query options, the
// handshake, the auth scheme, HEAD, Foxglove's session id, frames sent with the upgrade, the
// drop notice.

namespace {

// A WebSocket upgrade request for `target`, with `extra` header lines ("Name: value\r\n").
std::string upgrade_request(const std::string& target, const std::string& extra = "") {
  return "GET " + target +
         " HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
         "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n" +
         extra + "\r\n";
}

// An error reply's JSON body (null when it is none), from a raw exchange.
json error_body(const std::string& reply) {
  const auto head_end = reply.find("\r\n\r\n");
  if (head_end == std::string::npos) return nullptr;
  return json::parse(reply.substr(head_end + 4), nullptr, false);
}

// A telemetry stream asks for a rate that is a whole number token in (0, 5000] and for no option
// the server does not know: "20abc" was streamed at 20 rows/s and "?rate=5000" at the default 20,
// both without a word. The YAML start's ?speed= is read the same way.
TEST(ServerProtocol, TelemetryQueryOptionsAreWholeNumbersAndKnownNames) {
  ServerProcess server;
  struct Bad {
    std::string query, field;
  };
  for (const Bad& b : {Bad{"rate_hz=20abc", "rate_hz"}, Bad{"rate_hz=", "rate_hz"}, Bad{"rate_hz=nan", "rate_hz"},
                       Bad{"rate_hz=inf", "rate_hz"}, Bad{"rate_hz=1e400", "rate_hz"}, Bad{"rate_hz=0", "rate_hz"},
                       Bad{"rate_hz=5001", "rate_hz"}, Bad{"rate=5000", "rate"}, Bad{"rate_hz=20&x%ff=1", "x%FF"}}) {
    const std::string reply = raw_exchange(server.port(), upgrade_request("/api/telemetry?" + b.query));
    EXPECT_EQ(reply.rfind("HTTP/1.1 400", 0), 0u) << b.query << "\n" << reply;
    const json body = error_body(reply);
    ASSERT_TRUE(body.is_object()) << reply;
    EXPECT_EQ(body.value("field", ""), b.field) << b.query << "\n" << reply;
  }
  EXPECT_NE(error_body(raw_exchange(server.port(), upgrade_request("/api/telemetry?rate=5000")))
                .value("detail", "")
                .find("did you mean 'rate_hz'"),
            std::string::npos);
  EXPECT_EQ(raw_exchange(server.port(), upgrade_request("/api/telemetry?rate_hz=2.5")).rfind("HTTP/1.1 101", 0), 0u);

  const auto api = server.client();
  const auto start = api.request("POST", "/api/start?speed=2abc", hil::test::short_campaign_yaml(1), "application/yaml");
  EXPECT_EQ(start.status, 400) << start.body;
  EXPECT_EQ(start.json().value("field", ""), "speed") << start.body;
  EXPECT_EQ(api.get("/api/status").json()["state"], "idle");
}

// Every endpoint but the telemetry WebSocket ignored a query option it does not take: a typo
// (?wiat=0) got the report built and waited for, a JSON start's ?rig=hybrid started on sim, a
// cache-buster hid nothing. Each is refused by name before the handler runs (POST /api/stop?now=1
// while idle is 400, not stop's 409); token is every endpoint's.
TEST(ServerProtocol, EveryEndpointRefusesAQueryOptionItDoesNotTake) {
  ServerProcess server({}, "right-token-123");
  const auto api = server.client("right-token-123");
  struct Bad {
    std::string method, target, field, hint;
  };
  for (const Bad& b :
       {Bad{"GET", "/api/runs?runs=1", "runs", ""}, Bad{"GET", "/api/status?x%ff=1", "x%FF", ""},
        Bad{"GET", "/api/health?_=1700000000", "_", ""}, Bad{"GET", "/api/campaigns?name=paper_fig6", "name", ""},
        Bad{"GET", "/?console=1", "console", ""}, Bad{"GET", "/api/runs/nope/report.html?wiat=0", "wiat", "did you mean 'wait'"},
        Bad{"GET", "/api/runs/nope/telemetry.csv?wait=0", "wait", ""}, Bad{"POST", "/api/stop?now=1", "now", ""},
        Bad{"POST", "/api/inject/clear?all=1", "all", ""}}) {
    const auto reply = api.request(b.method, b.target, b.method == "POST" ? "{}" : "", "application/json");
    EXPECT_EQ(reply.status, 400) << b.method << " " << b.target << ": " << reply.body;
    const json body = json::parse(reply.body, nullptr, false);
    ASSERT_TRUE(body.is_object()) << reply.body;
    EXPECT_EQ(body.value("error", ""), "unknown query option") << reply.body;
    EXPECT_EQ(body.value("field", ""), b.field) << b.target << ": " << reply.body;
    EXPECT_NE(body.value("detail", "").find(b.hint), std::string::npos) << reply.body;
  }
  // The token in the query is no unknown option, and is not echoed in a refusal of another one.
  const auto anonymous = server.client("");
  EXPECT_EQ(anonymous.get("/api/status?token=right-token-123").status, 200);
  const auto with_token = anonymous.get("/api/status?token=right-token-123&verbose=1");
  EXPECT_EQ(with_token.status, 400) << with_token.body;
  EXPECT_EQ(with_token.body.find("right-token-123"), std::string::npos) << with_token.body;

  // A JSON start takes its options in the body; the query's are a YAML body's.
  const auto json_start = api.request("POST", "/api/start?rig=hybrid", campaign_request(1), "application/json");
  EXPECT_EQ(json_start.status, 400) << json_start.body;
  EXPECT_EQ(json_start.json().value("field", ""), "rig") << json_start.body;
  EXPECT_EQ(api.get("/api/status").json()["state"], "idle");

  // GET /api says which options each endpoint takes.
  const json index = api.get("/api").json();
  for (const auto& e : index["endpoints"]) {
    if (e["path"] == "/api/runs/{id}/report.html") {
      EXPECT_EQ(e["query"], json::array({"wait"})) << e.dump();
    }
    if (e["path"] == "/api/runs") {
      EXPECT_EQ(e["query"], json::array()) << e.dump();
    }
  }
}

// A start's subset of runs given empty ("runs": [], ?runs=) ran every run of the campaign, and one
// given twice was taken; both are refused naming 'runs', and nothing starts.
TEST(ServerProtocol, AnEmptyOrRepeatedSubsetOfRunsIsRefused) {
  ServerProcess server;
  const auto api = server.client();
  const std::string yaml = hil::test::short_campaign_yaml(2);
  for (const auto& reply : {api.post("/api/start", {{"campaign_yaml", yaml}, {"runs", json::array()}}),
                            api.post("/api/start", {{"campaign_yaml", yaml}, {"runs", {"adaptive", "adaptive"}}}),
                            api.request("POST", "/api/start?runs=", yaml, "application/yaml"),
                            api.request("POST", "/api/start?runs=,", yaml, "application/yaml"),
                            api.request("POST", "/api/start?runs=none,none", yaml, "application/yaml")}) {
    EXPECT_EQ(reply.status, 400) << reply.body;
    EXPECT_EQ(reply.json().value("field", ""), "runs") << reply.body;
    EXPECT_EQ(api.get("/api/status").json()["state"], "idle");
  }
}

// What the runner refuses in a start (a speed out of range or on a rig with hardware, a run the
// campaign does not have) was a 400 without "field"; every 400 names the field at fault.
TEST(ServerProtocol, AStartTheRunnerRefusesNamesTheField) {
  ServerProcess server;
  const auto api = server.client();
  const std::string yaml = hil::test::short_campaign_yaml(2);
  struct Bad {
    json body;
    std::string field;
  };
  for (const Bad& b :
       {Bad{{{"campaign_yaml", yaml}, {"speed", 0}}, "speed"}, Bad{{{"campaign_yaml", yaml}, {"speed", 101}}, "speed"},
        Bad{{{"campaign_yaml", yaml}, {"speed", 2}, {"rig", "hybrid"}}, "speed"},
        Bad{{{"campaign_yaml", yaml}, {"runs", {"adaptiv"}}}, "runs"}}) {
    const auto reply = api.post("/api/start", b.body);
    EXPECT_EQ(reply.status, 400) << reply.body;
    EXPECT_EQ(reply.json().value("field", ""), b.field) << b.body.dump() << ": " << reply.body;
  }
  EXPECT_EQ(api.get("/api/status").json()["state"], "idle");
}

// A report being made is written as RUN_DIR/report.html.tmp and renamed into place, so that half
// of one is never served; GET /api/runs/ID/report.html.tmp served it all the same.
TEST(ServerProtocol, AHalfMadeOutputIsNotServed) {
  ServerProcess server;
  const auto run = server.runs_dir() / "20261127T050000Z_tmp_adaptive";
  std::filesystem::create_directories(run);
  std::ofstream(run / "run.json") << "{}\n";
  std::ofstream(run / "report.html.tmp") << "<html><body>half a rep";
  const auto reply = server.client().get("/api/runs/20261127T050000Z_tmp_adaptive/report.html.tmp");
  EXPECT_EQ(reply.status, 404) << reply.body;
  EXPECT_EQ(reply.body.find("half a rep"), std::string::npos) << reply.body;
}

// An option given twice was read as its last value (?rate_hz=1&rate_hz=5000 streamed at 5000 rows
// a second), and report.html's ?wait= waited for any value but 0 (wait=false waited). Both are
// refused, naming the option, before the run is looked up; an empty part of a query ("?&") is no
// option.
TEST(ServerProtocol, AnOptionGivenTwiceOrAWaitOtherThan0Or1IsRefused) {
  ServerProcess server;
  const std::string twice = raw_exchange(server.port(), upgrade_request("/api/telemetry?rate_hz=1&rate_hz=5000"));
  EXPECT_EQ(twice.rfind("HTTP/1.1 400", 0), 0u) << twice;
  EXPECT_EQ(error_body(twice).value("field", ""), "rate_hz") << twice;
  EXPECT_EQ(error_body(twice).value("error", ""), "query option given twice") << twice;

  const auto api = server.client();
  for (const char* query : {"wait=0&wait=1", "wait=false", "wait=", "wait=01"}) {
    const auto reply = api.get(std::string("/api/runs/20261127T050000Z_nope_adaptive/report.html?") + query);
    EXPECT_EQ(reply.status, 400) << query << ": " << reply.body;
    EXPECT_EQ(reply.json().value("field", ""), "wait") << query << ": " << reply.body;
  }
  EXPECT_EQ(api.get("/api/runs/20261127T050000Z_nope_adaptive/report.html?wait=1").status, 404);
  EXPECT_EQ(api.get("/api/health?&").status, 200);
}

// What Beast refuses in a handshake (no Sec-WebSocket-Key, another version) was answered as plain
// text; every error of the API is a JSON body naming the field at fault.
TEST(ServerProtocol, WebSocketHandshakeRefusalsAreJsonErrorsNamingTheHeader) {
  ServerProcess server({}, "right-token-123");
  const std::string base =
      "GET /api/telemetry?token=right-token-123 HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n";
  const std::string no_key = raw_exchange(server.port(), base + "Sec-WebSocket-Version: 13\r\n\r\n");
  EXPECT_EQ(no_key.rfind("HTTP/1.1 400", 0), 0u) << no_key;
  EXPECT_NE(no_key.find("Content-Type: application/json"), std::string::npos) << no_key;
  EXPECT_EQ(error_body(no_key).value("field", ""), "Sec-WebSocket-Key") << no_key;
  const std::string old_version =
      raw_exchange(server.port(), base + "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 8\r\n\r\n");
  EXPECT_EQ(old_version.rfind("HTTP/1.1 426", 0), 0u) << old_version;
  EXPECT_EQ(error_body(old_version).value("field", ""), "Sec-WebSocket-Version") << old_version;
  // Refused before Beast (no token, a bad option): JSON too, and the token is not echoed.
  for (const std::string& refused : {raw_exchange(server.port(), upgrade_request("/api/telemetry")),
                                     raw_exchange(server.port(), upgrade_request("/")),  // not the token form
                                     raw_exchange(server.port(), upgrade_request("/api/telemetry?token=right-token-123&r=1"))}) {
    EXPECT_TRUE(error_body(refused).is_object()) << refused;
    EXPECT_EQ(refused.find("right-token-123"), std::string::npos) << refused;
  }
}

// RFC 9110: the auth scheme is case-insensitive; "bearer T" was refused. The token is not.
TEST(ServerProtocol, TheBearerSchemeIsCaseInsensitiveAndTheTokenIsNot) {
  ServerProcess server({}, "right-token-123");
  const auto status_with = [&](const std::string& authorization) {
    const std::string reply =
        raw_exchange(server.port(), "GET /api/status HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: " + authorization +
                                        "\r\nConnection: close\r\n\r\n");
    return reply.substr(0, 12);
  };
  EXPECT_EQ(status_with("bearer right-token-123"), "HTTP/1.1 200");
  EXPECT_EQ(status_with("BEARER  right-token-123"), "HTTP/1.1 200");
  EXPECT_EQ(status_with("Bearer right-token-123"), "HTTP/1.1 200");
  EXPECT_EQ(status_with("bearer RIGHT-TOKEN-123"), "HTTP/1.1 401");
  EXPECT_EQ(status_with("bearer right-token-12"), "HTTP/1.1 401");
  EXPECT_EQ(status_with("bearerright-token-123"), "HTTP/1.1 401");
  EXPECT_EQ(status_with("Basic right-token-123"), "HTTP/1.1 401");
  EXPECT_EQ(status_with("bearer "), "HTTP/1.1 401");
}

// A HEAD was answered 405 with a body: on a kept-alive connection the client read that body as
// the start of the next answer. HEAD mirrors GET's header without the body, and where there is
// no GET it is a 405 without a body; the answer after it parses.
TEST(ServerProtocol, HeadIsAnsweredWithoutABodyAndTheConnectionStaysInStep) {
  ServerProcess server;
  const auto run = server.runs_dir() / "20261127T050000Z_head_adaptive";  // a file is sent from disk
  std::filesystem::create_directories(run);
  std::ofstream(run / "run.json") << "{}\n";
  std::ofstream(run / "telemetry.csv") << "t_s,p_meas_mpa\n0,1\n";
  const std::string get_body = server.client().get("/api/health").body;
  const std::string reply = raw_exchange(server.port(),
                                         "HEAD /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"
                                         "HEAD /api/start HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"
                                         "HEAD /api/runs/20261127T050000Z_head_adaptive/telemetry.csv HTTP/1.1\r\n"
                                         "Host: 127.0.0.1\r\n\r\n"
                                         "GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n");
  std::vector<std::string> heads;
  std::size_t at = 0;
  for (int i = 0; i < 4; ++i) {
    const auto end = reply.find("\r\n\r\n", at);
    ASSERT_NE(end, std::string::npos) << reply;
    heads.push_back(reply.substr(at, end - at));
    at = end + 4;
    if (i < 3) {
      ASSERT_EQ(reply.compare(at, 9, "HTTP/1.1 "), 0) << "a body after answer " << i + 1 << ":\n" << reply;
    }
  }
  EXPECT_EQ(heads[0].rfind("HTTP/1.1 200", 0), 0u) << heads[0];
  EXPECT_NE(heads[0].find("Content-Length: " + std::to_string(get_body.size())), std::string::npos) << heads[0];
  EXPECT_EQ(heads[1].rfind("HTTP/1.1 405", 0), 0u) << heads[1];
  EXPECT_NE(heads[1].find("\r\nAllow: POST\r\n"), std::string::npos) << heads[1];  // RFC 9110 15.5.6: a 405 says what is
  EXPECT_EQ(heads[2].rfind("HTTP/1.1 200", 0), 0u) << heads[2];
  EXPECT_NE(heads[2].find("Content-Length: 19"), std::string::npos) << heads[2];
  EXPECT_EQ(heads[3].rfind("HTTP/1.1 200", 0), 0u) << heads[3];
  EXPECT_EQ(json::parse(reply.substr(at)).value("ok", false), true) << reply;
}

// A HEAD of a run's report.html made the report (queued on the job worker, waited for, written
// into the run folder) only to drop its body. HEAD answers the header of what GET would send and
// makes nothing: no report.html appears; once GET has made it, HEAD gives its exact length.
TEST(ServerProtocol, HeadOfAReportNotMadeYetDoesNotMakeIt) {
  ServerProcess server;
  const auto api = server.client();
  ASSERT_EQ(api.request("POST", "/api/start", campaign_request(1), "application/json").status, 202);
  hil::test::wait_status(
      api, [](const json& s) { return s["state"] == "idle" && s["last"].is_object(); }, 30s);
  const auto run = hil::test::only_run(server.runs_dir());
  const std::string target = "/api/runs/" + run.filename().string() + "/report.html";
  const auto head = [&](const std::string& t) {
    const std::string reply =
        raw_exchange(server.port(), "HEAD " + t + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n");
    const auto end = reply.find("\r\n\r\n");
    EXPECT_EQ(end + 4, reply.size()) << "a body after the header:\n" << reply;
    return reply.substr(0, end + 2);
  };

  for (const std::string& t : {target, target + "?wait=0"}) {
    const std::string not_made = head(t);
    EXPECT_EQ(not_made.rfind("HTTP/1.1 200", 0), 0u) << not_made;
    EXPECT_NE(not_made.find("Content-Type: text/html; charset=utf-8\r\n"), std::string::npos) << not_made;
    EXPECT_EQ(not_made.find("Content-Length"), std::string::npos) << "the length of a report not made is not known:\n"
                                                                  << not_made;
  }
  std::this_thread::sleep_for(1s);  // a report of a 1 s run takes a tenth of that
  EXPECT_FALSE(std::filesystem::exists(run / "report.html")) << "HEAD made the report";
  EXPECT_FALSE(std::filesystem::exists(run / "report.html.tmp")) << "HEAD is making the report";

  const auto made = api.get(target);
  ASSERT_EQ(made.status, 200) << made.body.substr(0, 300);
  ASSERT_TRUE(std::filesystem::exists(run / "report.html"));
  const std::string kept = head(target);
  EXPECT_EQ(kept.rfind("HTTP/1.1 200", 0), 0u) << kept;
  EXPECT_NE(kept.find("Content-Length: " + std::to_string(made.body.size()) + "\r\n"), std::string::npos) << kept;
  EXPECT_NE(kept.find("Content-Type: text/html; charset=utf-8\r\n"), std::string::npos) << kept;

  EXPECT_EQ(head("/api/runs/20261127T050000Z_nope_adaptive/report.html").rfind("HTTP/1.1 404", 0), 0u);
}

// ctl telemetry said only "the WebSocket handshake was declined"; it says the server's status and
// error now, as every other ctl command does.
TEST(ServerProtocol, CtlTelemetrySaysWhyTheServerRefusedTheStream) {
  ServerProcess server({}, "right-token-123");
  const std::string ctl =
      "timeout 60 " + hil::test::hilbench_exe() + " ctl --server http://127.0.0.1:" + std::to_string(server.port());
  const auto too_fast = hil::test::run_command(ctl + " --token right-token-123 telemetry --rate-hz 6000 --count 1");
  EXPECT_EQ(too_fast.status, 1) << too_fast.output;
  EXPECT_NE(too_fast.output.find("(field 'rate_hz')"), std::string::npos) << too_fast.output;
  EXPECT_NE(too_fast.output.find("(HTTP 400)"), std::string::npos) << too_fast.output;
  // %g writes 1e+06, whose '+' a query reads as a space: the server must be told the number sent.
  const auto far_too_fast = hil::test::run_command(ctl + " --token right-token-123 telemetry --rate-hz 1000000 --count 1");
  EXPECT_EQ(far_too_fast.status, 1) << far_too_fast.output;
  EXPECT_NE(far_too_fast.output.find("must be in (0, 5000]"), std::string::npos) << far_too_fast.output;
  const auto no_token = hil::test::run_command(ctl + " telemetry --count 1");
  EXPECT_EQ(no_token.status, 1) << no_token.output;
  EXPECT_NE(no_token.output.find("unauthorized"), std::string::npos) << no_token.output;
  EXPECT_NE(no_token.output.find("(HTTP 401)"), std::string::npos) << no_token.output;
}

const std::string kFoxglove = "Sec-WebSocket-Protocol: foxglove.websocket.v1\r\n";

// Reads until `pending` holds `n` bytes; false at the end of the stream or the read timeout.
bool fill(int fd, std::string& pending, std::size_t n) {
  char buf[8192];
  while (pending.size() < n) {
    const ssize_t got = ::recv(fd, buf, sizeof buf, 0);
    if (got <= 0) return false;
    pending.append(buf, static_cast<std::size_t>(got));
  }
  return true;
}

// The server's next message (continuation frames joined; a control frame comes alone): opcode and
// payload, or nullopt at the end of the stream or the read timeout. `pending`: bytes read ahead.
std::optional<std::pair<int, std::string>> next_message(int fd, std::string& pending) {
  std::optional<std::pair<int, std::string>> message;
  for (;;) {
    if (!fill(fd, pending, 2)) return std::nullopt;
    const int opcode = pending[0] & 0x0f;
    const bool fin = (pending[0] & 0x80) != 0;
    std::size_t size = pending[1] & 0x7f, at = 2;
    if (size == 126 || size == 127) {
      const std::size_t bytes = size == 126 ? 2 : 8;
      if (!fill(fd, pending, 2 + bytes)) return std::nullopt;
      size = 0;
      for (std::size_t i = 0; i < bytes; ++i) size = size << 8 | static_cast<unsigned char>(pending[2 + i]);
      at += bytes;
    }
    if (!fill(fd, pending, at + size)) return std::nullopt;
    std::string payload = pending.substr(at, size);
    pending.erase(0, at + size);
    if (opcode >= 8) return std::pair<int, std::string>{opcode, payload};
    if (!message) message.emplace(opcode, "");
    message->second += payload;
    if (fin) return message;
  }
}

// Sends the upgrade (and anything after it in the same write) and reads the 101's header; the
// bytes read past it stay in `pending`. False when the answer is not a 101.
bool open_stream(int fd, const std::string& bytes_for_host, std::string& pending) {
  const std::string bytes = with_port(bytes_for_host, peer_port(fd));
  if (::send(fd, bytes.data(), bytes.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(bytes.size())) return false;
  while (pending.find("\r\n\r\n") == std::string::npos) {
    if (!fill(fd, pending, pending.size() + 1)) return false;
  }
  const bool upgraded = pending.rfind("HTTP/1.1 101", 0) == 0;
  pending.erase(0, pending.find("\r\n\r\n") + 4);
  return upgraded;
}

// Foxglove's sessionId was the session's heap address: it told any client the server's memory
// layout, and differed per connection, so a client could not tell a reconnect from a restart.
TEST(ServerProtocol, TheFoxgloveSessionIdIsTheServersAndNoAddress) {
  ServerProcess server;
  std::vector<std::string> ids;
  std::vector<int> fds;
  for (int i = 0; i < 2; ++i) {  // both open at once: two sessions alive at two addresses
    fds.push_back(hil::test::connect_loopback(server.port()));
    std::string pending;
    ASSERT_TRUE(open_stream(fds.back(), upgrade_request("/api/telemetry", kFoxglove), pending));
    const auto info = next_message(fds.back(), pending);
    ASSERT_TRUE(info.has_value());
    const json j = json::parse(info->second);
    ASSERT_EQ(j.value("op", ""), "serverInfo") << info->second;
    ids.push_back(j.value("sessionId", ""));
  }
  for (const int fd : fds) ::close(fd);
  EXPECT_FALSE(ids[0].empty());
  EXPECT_EQ(ids[0], ids[1]);
  EXPECT_NE(ids[0].find_first_not_of("0123456789"), std::string::npos) << ids[0];  // not a pointer's decimal
}

// A client's frame: final, masked as RFC 6455 requires of a client. opcode 1 text, 9 ping.
std::string client_frame(std::uint8_t opcode, std::string_view payload) {
  std::string f{static_cast<char>(0x80 | opcode)};
  const std::array<char, 4> mask = {0x12, 0x34, 0x56, 0x78};
  if (payload.size() < 126) {
    f.push_back(static_cast<char>(0x80 | payload.size()));
  } else {
    f += {static_cast<char>(0x80 | 126), static_cast<char>(payload.size() >> 8), static_cast<char>(payload.size() & 0xff)};
  }
  f.append(mask.data(), mask.size());
  for (std::size_t i = 0; i < payload.size(); ++i) f.push_back(static_cast<char>(payload[i] ^ mask[i % 4]));
  return f;
}

// A client that sends the upgrade and its first frames in one write (a Foxglove subscribe, a
// ping) is answered: those bytes were read by the HTTP session and lost at the hand-over.
TEST(ServerProtocol, FramesSentWithTheUpgradeAreRead) {
  ServerProcess server;
  const int fd = hil::test::connect_loopback(server.port(), 10);
  std::string pending;
  ASSERT_TRUE(open_stream(fd,
                          upgrade_request("/api/telemetry", kFoxglove) +
                              client_frame(1, R"({"op":"subscribe","subscriptions":[{"id":1,"channelId":999}]})") +
                              client_frame(9, "are you there"),
                          pending));
  std::vector<std::pair<int, std::string>> got;
  for (int i = 0; i < 4; ++i) {
    const auto m = next_message(fd, pending);
    if (!m) break;
    got.push_back(*m);
  }
  ::close(fd);
  ASSERT_EQ(got.size(), 4u) << "the frames sent with the upgrade were not answered";
  // Beast sends the pong as it reads the ping, before or after the messages the session queued.
  std::vector<std::string> ops;
  for (const auto& [opcode, payload] : got) {
    if (opcode == 10) {
      EXPECT_EQ(payload, "are you there");
      continue;
    }
    const json j = json::parse(payload);
    ops.push_back(j.value("op", ""));
    if (ops.back() == "status") {
      EXPECT_NE(j.value("message", "").find("channel 999 is not advertised"), std::string::npos) << payload;
    }
  }
  EXPECT_EQ(ops, (std::vector<std::string>{"serverInfo", "advertise", "status"}));
}

// A Foxglove client that sends requests without reading the answers: the answers it cannot take
// are not telemetry, and the client is not told it missed telemetry (it was, once the server's
// queue was full of answers to its own bad requests).
TEST(ServerProtocol, AnswersAClientDidNotReadAreNotCalledDroppedTelemetry) {
  ServerProcess server;  // idle: no telemetry flows at all
  const int fd = hil::test::connect_loopback(server.port(), 3);
  const int small = 4096;  // the server's sends stall at once
  ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
  std::string pending;
  ASSERT_TRUE(open_stream(fd, upgrade_request("/api/telemetry", kFoxglove), pending));
  std::string requests;
  for (int i = 0; i < 3000; ++i) requests += client_frame(1, R"({"op":"nothing"})");
  ASSERT_EQ(::send(fd, requests.data(), requests.size(), MSG_NOSIGNAL), static_cast<ssize_t>(requests.size()));
  std::size_t answers = 0;
  std::vector<std::string> dropped;
  while (const auto m = next_message(fd, pending)) {  // until 3 s pass without a message
    if (m->second.find("\"status\"") == std::string::npos) continue;
    if (m->second.find("dropped") != std::string::npos) {
      dropped.push_back(m->second);
    } else {
      ++answers;
    }
  }
  ::close(fd);
  EXPECT_TRUE(dropped.empty()) << dropped.front();
  EXPECT_GT(answers, 0u);
  EXPECT_EQ(server.client().get("/api/health").status, 200);
}

}  // namespace

// A copy of the bench's configs (and the driver files its rigs name) in `base`, with a rig named
// `rig` like modbus.yaml whose transducer's register map is padded with comments to about
// `map_bytes` (valid YAML, the same map). Returns the configs folder.
std::filesystem::path configs_with_padded_map(const std::filesystem::path& base, const std::string& rig, std::size_t map_bytes) {
  const auto configs = base / "configs", drivers = base / "drivers" / "configs";
  std::filesystem::create_directories(drivers);
  std::filesystem::copy(hil::test::source_path("configs"), configs, std::filesystem::copy_options::recursive);
  std::filesystem::copy(hil::test::source_path("drivers/configs"), drivers, std::filesystem::copy_options::recursive);
  {
    std::ofstream map(drivers / (rig + "_map.yaml"));
    map << hil::test::slurp(drivers / "modbus_transducer_map.yaml");
    const std::string padding = "# " + std::string(98, '-') + "\n";
    for (std::size_t bytes = 0; bytes < map_bytes; bytes += padding.size()) map << padding;
  }
  std::string text = hil::test::slurp(configs / "rigs" / "modbus.yaml");
  text.replace(text.find("modbus_transducer_map.yaml"), std::string("modbus_transducer_map.yaml").size(), rig + "_map.yaml");
  std::ofstream(configs / "rigs" / (rig + ".yaml")) << text;
  return configs;
}

// A rig whose register map is megabytes (a tester's 6.7 MB map kept the server's I/O thread, and
// every request with it, for 60 s at each GET /api/rigs): refused unread past 1 MiB, the rig
// listed with an error naming the file and the limit; the other rigs are listed as before.
TEST(ServerProtocol, AHugeRegisterMapIsRefusedNamingTheFileAndTheLimit) {
  hil::test::TempDir base;
  ServerProcess server({"--configs", configs_with_padded_map(base.path(), "huge", 1'200'000).string()});
  const json rigs = server.client().get("/api/rigs").json()["rigs"];
  ASSERT_EQ(rigs.size(), 5u) << rigs.dump(2);
  for (const auto& r : rigs) {
    if (r["name"] != "huge") {
      EXPECT_FALSE(r.contains("error")) << r.dump(2);
      continue;
    }
    const std::string error = r.value("error", "");
    EXPECT_NE(error.find("huge_map.yaml: "), std::string::npos) << error;
    EXPECT_NE(error.find("more than the 1048576 bytes (1 MiB) a YAML config file may have"), std::string::npos) << error;
  }
  const auto start = server.client().post("/api/start", {{"campaign", "paper_adaptive"}, {"rig", "huge"}});
  // "invalid rig file", as for any rig file that does not load: the operator's to fix, no 500.
  EXPECT_EQ(start.status, 409) << start.body;
  EXPECT_EQ(start.json().value("field", ""), "rig") << start.body;
  EXPECT_NE(start.body.find("huge_map.yaml"), std::string::npos) << start.body;
}

// A rig with a real drive says in GET /api/rigs whether it watches the drive's following error
// (the shipped ones: 3 deg for 100 ms; sim: null), and one without the limit is listed, and
// started, with a warning that names the key: a frozen encoder would trip no interlock there.
TEST(ServerProtocol, ADriveRigWithoutAFollowingErrorLimitIsListedAndStartedWithAWarning) {
  hil::test::TempDir base;
  const auto configs = configs_with_padded_map(base.path(), "nofollow", 0);
  std::string text = hil::test::slurp(configs / "rigs" / "nofollow.yaml");
  const auto line = text.find("  following_error:");
  ASSERT_NE(line, std::string::npos);
  text.erase(line, text.find('\n', line) + 1 - line);
  std::ofstream(configs / "rigs" / "nofollow.yaml") << text;
  ServerProcess server({"--configs", configs.string()});
  const json rigs = server.client().get("/api/rigs").json()["rigs"];
  const auto rig = [&](const std::string& name) {
    const auto it = std::find_if(rigs.begin(), rigs.end(), [&](const json& r) { return r["name"] == name; });
    EXPECT_NE(it, rigs.end()) << name << ": " << rigs.dump(2);
    return it == rigs.end() ? json::object() : *it;
  };
  for (const char* name : {"can", "modbus", "hybrid"}) {
    EXPECT_EQ(rig(name)["following_error"], (json{{"max_deg", 3.0}, {"time_ms", 100}})) << name;
    EXPECT_FALSE(rig(name).contains("warning")) << name;
  }
  EXPECT_TRUE(rig("sim")["following_error"].is_null());
  EXPECT_FALSE(rig("sim").contains("warning"));
  EXPECT_TRUE(rig("nofollow")["following_error"].is_null());
  const std::string warning = rig("nofollow").value("warning", "");
  EXPECT_NE(warning.find("rig 'nofollow' drives a real motor without safety.following_error"), std::string::npos) << warning;

  // Started on it (nothing listens on its ports: the run ends in a setup error), the start's
  // answer carries the same warning.
  const auto start = server.client().post("/api/start", {{"campaign", "paper_adaptive"}, {"rig", "nofollow"}});
  ASSERT_EQ(start.status, 202) << start.body;
  EXPECT_EQ(start.json().value("warning", ""), warning) << start.body;
}

// The bytes the server process has read so far (its /proc/PID/io rchar: files and sockets).
std::uint64_t bytes_read(pid_t pid) {
  std::ifstream io("/proc/" + std::to_string(pid) + "/io");
  for (std::string key; io >> key;) {
    std::uint64_t value = 0;
    io >> value;
    if (key == "rchar:") return value;
  }
  return 0;
}

// GET /api/rigs loads each rig with its device files and register maps on the I/O thread; an
// unchanged rig is not read again (a 900 KB register map was read and parsed at every request),
// and a change to any file a rig's load read (here its register map, not the rig file) is seen.
TEST(ServerProtocol, AnUnchangedRigIsNotReadAgainAndAChangeToItsRegisterMapIs) {
  hil::test::TempDir base;
  const auto configs = configs_with_padded_map(base.path(), "padded", 900'000);
  ServerProcess server({"--configs", configs.string()});
  const auto api = server.client();
  const std::string first = api.get("/api/rigs").body;
  EXPECT_EQ(first.find("\"error\""), std::string::npos) << first;
  const std::uint64_t before = bytes_read(server.pid());
  const std::string second = api.get("/api/rigs").body;
  EXPECT_LT(bytes_read(server.pid()) - before, 100'000u) << "the rigs were read again";
  EXPECT_EQ(second, first);

  std::ofstream(base.path() / "drivers" / "configs" / "padded_map.yaml", std::ios::app) << "bits: {fault: 1}\n";
  const json rigs = api.get("/api/rigs").json()["rigs"];
  const auto padded = std::find_if(rigs.begin(), rigs.end(), [](const json& r) { return r["name"] == "padded"; });
  ASSERT_NE(padded, rigs.end()) << rigs.dump(2);
  EXPECT_NE(padded->value("error", "").find("duplicate key 'bits'"), std::string::npos) << padded->dump(2);
}

// GET /api/campaigns and GET /api/models parsed every file at each request, on the I/O thread.
// They keep each entry as GET /api/rigs does: an unchanged campaign or model is not read again,
// and a change to any file its load read is seen: the plant a campaign names (not the campaign
// file), by both; a campaign's reference CSV (read by the CSV reader, not as YAML).
TEST(ServerProtocol, UnchangedCampaignsAndModelsAreNotReadAgainAndAChangeToThePlantIs) {
  hil::test::TempDir base;
  const auto configs = configs_with_padded_map(base.path(), "padded", 0);
  const std::string padding = [] {
    std::string p;
    for (int i = 0; i < 9000; ++i) p += "# " + std::string(98, '-') + "\n";  // 900 KB of comment
    return p;
  }();
  std::ofstream(configs / "plant" / "padded.yaml") << hil::test::slurp(configs / "plant" / "nominal.yaml") << padding;
  std::string campaign = hil::test::slurp(configs / "campaigns" / "paper_adaptive.yaml");
  campaign.replace(campaign.find("../plant/nominal.yaml"), std::string("../plant/nominal.yaml").size(), "../plant/padded.yaml");
  std::ofstream(configs / "campaigns" / "padded.yaml") << campaign << padding;
  std::string from_csv = hil::test::short_campaign_yaml(2, "from_csv");
  const std::string square = "    - square: {from_s: 0.5, half_period_s: 1.0, low_mpa: 1.0, high_mpa: 1.5}\n";
  from_csv.replace(from_csv.find(square), square.size(), "    - csv: {file: reference.csv}\n");
  std::ofstream(configs / "campaigns" / "from_csv.yaml") << from_csv;
  std::ofstream(configs / "campaigns" / "reference.csv") << "t_s,p_ref_mpa\n0,1.0\n1,1.5\n";
  ServerProcess server({"--configs", configs.string()});
  const auto api = server.client();

  const std::string campaigns = api.get("/api/campaigns").body, models = api.get("/api/models").body;
  EXPECT_EQ(campaigns.find("\"error\""), std::string::npos) << campaigns;
  EXPECT_EQ(models.find("\"error\""), std::string::npos) << models;
  const std::uint64_t before = bytes_read(server.pid());
  EXPECT_EQ(api.get("/api/campaigns").body, campaigns);
  EXPECT_EQ(api.get("/api/models").body, models);
  EXPECT_LT(bytes_read(server.pid()) - before, 100'000u) << "the campaigns or models were read again";

  std::ofstream(configs / "plant" / "padded.yaml", std::ios::app) << "description: twice\n";
  std::ofstream(configs / "campaigns" / "reference.csv") << "t_s,p_ref_mpa\n";
  for (const auto& [path, key] : {std::pair{"/api/campaigns", "campaigns"}, std::pair{"/api/models", "models"}}) {
    const json list = api.get(path).json()[key];
    const auto padded = std::find_if(list.begin(), list.end(), [](const json& e) { return e["name"] == "padded"; });
    ASSERT_NE(padded, list.end()) << list.dump(2);
    EXPECT_NE(padded->value("error", "").find("duplicate key 'description'"), std::string::npos) << path << padded->dump(2);
  }
  const json campaigns_now = api.get("/api/campaigns").json()["campaigns"];
  const auto csv =
      std::find_if(campaigns_now.begin(), campaigns_now.end(), [](const json& e) { return e["name"] == "from_csv"; });
  ASSERT_NE(csv, campaigns_now.end()) << campaigns_now.dump(2);
  EXPECT_NE(csv->value("error", "").find("the file has no rows"), std::string::npos) << csv->dump(2);
}
