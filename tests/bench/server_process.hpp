// The real `hilbench serve` process on an ephemeral 127.0.0.1 port, for end-to-end tests that
// drive it only through its API. Its output goes to a log file printed when a test fails.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "hil/bench/server/api_client.hpp"
#include "temp_file.hpp"

extern char** environ;

namespace hil::test {

// Runs a program; stdout and stderr go to `log`. Returns the pid.
inline pid_t spawn(const std::vector<std::string>& argv, const std::filesystem::path& log) {
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, args[0], &fa, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) throw std::runtime_error("cannot start " + argv[0]);
  return pid;
}

// Waits for a child; the exit code, -signal if it died of one, nullopt on timeout.
inline std::optional<int> wait_exit(pid_t pid, std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    int status = 0;
    const pid_t r = waitpid(pid, &status, WNOHANG);
    if (r == pid) return WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status);
    if (std::chrono::steady_clock::now() > end) return std::nullopt;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
}

inline std::string hilbench_exe() { return HILBENCH_EXE; }

// A connected TCP socket to 127.0.0.1:port (-1 if refused); reads give up after `wait_s` (a
// failure, not a hang). For raw exchanges the HTTP client would not send.
inline int connect_loopback(int port, long wait_s = 30) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return -1;
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    ::close(fd);
    return -1;
  }
  const timeval wait{wait_s, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &wait, sizeof wait);
  return fd;
}

class ServerProcess {
 public:
  explicit ServerProcess(std::vector<std::string> extra = {}, std::string token = "") : token_(std::move(token)) {
    log_ = dir_.path() / "server.log";
    std::vector<std::string> argv = {hilbench_exe(), "serve",
                                     "--listen",     "127.0.0.1:0",
                                     "--configs",    source_path("configs").string(),
                                     "--runs-dir",   runs_dir().string(),
                                     "--port-file",  (dir_.path() / "port").string()};
    for (auto& a : extra) argv.push_back(std::move(a));
    if (!token_.empty()) argv.insert(argv.end(), {"--token", token_});
    pid_ = spawn(argv, log_);
    for (int i = 0; i < 6000 && !std::filesystem::exists(dir_.path() / "port"); ++i) {  // 60 s: the vcan VM is slow to start
      if (const auto rc = wait_exit(pid_, std::chrono::milliseconds(10))) {
        pid_ = 0;
        throw std::runtime_error("hilbench serve exited with " + std::to_string(*rc) + ":\n" + slurp(log_));
      }
    }
    port_ = std::stoi(slurp(dir_.path() / "port"));
  }
  ~ServerProcess() {
    if (pid_ > 0) {
      kill(pid_, SIGTERM);
      if (!wait_exit(pid_, std::chrono::seconds(10))) {
        kill(pid_, SIGKILL);
        wait_exit(pid_, std::chrono::seconds(5));
      }
    }
    if (::testing::Test::HasFailure())
      std::fprintf(stderr, "---- server log ----\n%s--------------------\n", slurp(log_).c_str());
  }
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;

  bench::ApiClient client(const std::string& token) const {
    return bench::ApiClient("http://127.0.0.1:" + std::to_string(port_), token, std::chrono::seconds(20));
  }
  bench::ApiClient client() const { return client(token_); }
  int port() const { return port_; }
  pid_t pid() const { return pid_; }
  std::filesystem::path runs_dir() const { return dir_.path() / "runs"; }
  const std::filesystem::path& dir() const { return dir_.path(); }
  std::string log() const { return slurp(log_); }
  // SIGTERM, then the exit code (nullopt: still running after the timeout).
  std::optional<int> terminate(std::chrono::milliseconds timeout) {
    kill(pid_, SIGTERM);
    const auto rc = wait_exit(pid_, timeout);
    if (rc) pid_ = 0;
    return rc;
  }

 private:
  TempDir dir_;
  std::filesystem::path log_;
  std::string token_;
  pid_t pid_ = 0;
  int port_ = 0;
};

// The single run folder a test produced.
inline std::filesystem::path only_run(const std::filesystem::path& runs_dir) {
  std::vector<std::filesystem::path> dirs;
  for (const auto& e : std::filesystem::directory_iterator(runs_dir)) {
    if (e.is_directory()) dirs.push_back(e.path());
  }
  if (dirs.size() != 1)
    throw std::runtime_error("expected one run folder in " + runs_dir.string() + ", found " + std::to_string(dirs.size()));
  return dirs.front();
}

inline std::vector<nlohmann::json> read_jsonl(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::vector<nlohmann::json> out;
  for (std::string line; std::getline(in, line);) out.push_back(nlohmann::json::parse(line));
  return out;
}

// A short campaign like paper_adaptive (the nominal plant, both runs), as YAML to post: the
// reference alternates 1.0 / 1.5 MPa every second from 0.5 s. Its plant path resolves from the
// server's campaigns folder.
inline std::string short_campaign_yaml(double duration_s, const std::string& name = "short_adaptive") {
  return "name: " + name +
         "\n"
         "description: a short test campaign\n"
         "plant: ../plant/nominal.yaml\n"
         "duration_s: " +
         std::to_string(duration_s) +
         "\n"
         "period_ms: 1\n"
         "seed: 1\n"
         "sensor_noise_kpa: 2.0\n"
         "reference:\n"
         "  initial_mpa: 1.0\n"
         "  profile:\n"
         "    - square: {from_s: 0.5, half_period_s: 1.0, low_mpa: 1.0, high_mpa: 1.5}\n"
         "gap:\n"
         "  initial_deg: 1.0\n"
         "runs:\n"
         "  - name: none\n"
         "    compensation: none\n"
         "  - name: adaptive\n"
         "    compensation: adaptive\n"
         "    initial_gap_deg: 0\n";
}

// Polls status until `pred` holds or the timeout passes; returns the last status.
template <class Pred>
nlohmann::json wait_status(const bench::ApiClient& api, Pred pred, std::chrono::seconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  nlohmann::json s;
  do {
    s = api.get("/api/status").json();
    if (pred(s)) return s;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  } while (std::chrono::steady_clock::now() < end);
  return s;
}

inline double status_t(const nlohmann::json& s) { return s.contains("progress") ? s["progress"].value("t_s", 0.0) : 0.0; }

}  // namespace hil::test
