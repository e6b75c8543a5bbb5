// hilbench serve [--listen HOST:PORT] [--token T] [--configs DIR] [--runs-dir DIR] [--port-file F]
//                [--max-body-kb N] [--max-waiting-jobs N] [--no-mlock] [--allow-host NAME]... [--ws-idle-timeout-s N]
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <memory>
#include <optional>
#include <thread>
#include <vector>

#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/signal_set.hpp>
#include <spdlog/spdlog.h>

#include "commands.hpp"
#include "hil/output_path.hpp"
#include "hil/bench/rt/rt_thread.hpp"
#include "hil/bench/server/runner.hpp"
#include "hil/file_lock.hpp"
#include "hil/line_file.hpp"
#include "server/api_server.hpp"
#include "server/operator_link.hpp"
#include "server/status_stream.hpp"

namespace hil::bench {

namespace {

std::pair<std::string, unsigned short> split_listen(const std::string& listen) {
  std::string host = listen, port = "8470";
  if (!listen.empty() && listen.front() == '[') {  // [::1]:8470
    const auto close = listen.find(']');
    if (close == std::string::npos) throw UsageError("--listen '" + listen + "': missing ']'");
    host = listen.substr(1, close - 1);
    if (close + 1 < listen.size() && listen[close + 1] == ':') port = listen.substr(close + 2);
  } else if (const auto colon = listen.rfind(':'); colon != std::string::npos && listen.find(':') == colon) {
    host = listen.substr(0, colon);
    port = listen.substr(colon + 1);
  }
  try {
    const long p = std::stol(port);
    if (p < 0 || p > 65535) throw std::out_of_range(port);
    return {host, static_cast<unsigned short>(p)};
  } catch (const std::exception&) {
    throw UsageError("--listen '" + listen + "': the port must be 0..65535");
  }
}

struct ServeArgs {
  std::string listen = "127.0.0.1:8470";
  std::string token;  // empty: no token required
  std::string configs_dir = "configs";
  std::string runs_dir = "runs";
  std::string port_file;  // empty: none
  std::size_t max_body_kb = 1024;
  std::size_t max_waiting_jobs = 8;
  std::int64_t max_diagnose_mb = 0;  // 0: a quarter of the machine's memory
  bool no_mlock = false;
  std::vector<std::string> allow_hosts;
  double ws_idle_timeout_s = 300;
};

int run_serve(const ServeArgs& args) {
  if (!args.port_file.empty()) check_output_file("--port-file", args.port_file, {}, "the port file");
  ApiOptions api;
  std::tie(api.address, api.port) = split_listen(args.listen);
  api.token = args.token;
  const std::filesystem::path configs = args.configs_dir;
  api.campaigns_dir = configs / "campaigns";
  api.rigs_dir = configs / "rigs";
  api.plant_dir = configs / "plant";
  api.runs_dir = args.runs_dir;
  api.version = HIL_VERSION;
  api.max_body_bytes = args.max_body_kb * 1024;
  api.max_waiting_jobs = args.max_waiting_jobs;
  api.allow_hosts = args.allow_hosts;
  api.ws_idle_timeout = std::chrono::milliseconds(std::llround(args.ws_idle_timeout_s * 1000));
  if (args.max_diagnose_mb > 0) {
    api.max_diagnose_bytes = static_cast<std::uint64_t>(args.max_diagnose_mb) << 20;
  } else {
    const long pages = ::sysconf(_SC_PHYS_PAGES), page_bytes = ::sysconf(_SC_PAGESIZE);
    if (pages > 0 && page_bytes > 0) api.max_diagnose_bytes = static_cast<std::uint64_t>(pages) * page_bytes / 4;
  }
  for (const auto& dir : {api.campaigns_dir, api.rigs_dir}) {
    if (!std::filesystem::is_directory(dir)) {
      throw std::runtime_error("no folder " + dir.string() + " (give --configs DIR, the folder holding campaigns/ and rigs/)");
    }
  }
  std::filesystem::create_directories(api.runs_dir);
  // One server a runs folder: a second one's start cleans what it takes for leftovers (the first
  // one's half-made reports and analyses) and marks runs. Held until the process ends; the kernel
  // drops it with a server that dies, so a restart after a crash is never refused.
  std::optional<hil::FileLock> runs_lock;
  try {
    runs_lock.emplace(api.runs_dir / ".server.lock");
  } catch (const hil::FileLock::Busy&) {
    throw std::runtime_error("another hilbench serve uses the runs folder " + api.runs_dir.string() + " (it holds " +
                             (api.runs_dir / ".server.lock").string() + "); give each server its own --runs-dir");
  }
  // Runs a dead server left "running" get their honest end before anyone lists them.
  for (const auto& dir : mark_interrupted_runs(api.runs_dir)) {
    spdlog::warn("run {}: its server ended during the run; marked interrupted", dir.filename().string());
  }

  std::string mlock_warning = "not requested (--no-mlock)";
  if (!args.no_mlock) {
    mlock_warning = lock_memory();
    if (!mlock_warning.empty()) spdlog::warn("{}", mlock_warning);
  }

  // Destruction order matters: the runner ends before the io_context, whose pending handlers
  // (sessions) still unsubscribe from the hub when it is destroyed.
  TelemetryHub hub;
  boost::asio::io_context io;
  // The hub's fan-out thread posts to io's sessions: it ends before io does.
  const std::unique_ptr<TelemetryHub, void (*)(TelemetryHub*)> hub_stops_first(&hub, [](TelemetryHub* h) { h->stop(); });
  RunnerOptions ro;
  ro.runs_dir = api.runs_dir;
  ro.version = HIL_VERSION;
  ro.mlock_warning = mlock_warning;
  ro.last_run = newest_ended_run(api.runs_dir);  // an interrupted run above included: the console says what became of it
  ro.on_row = [&hub](const TelemetryRecord& r) { hub.publish_row(r); };
  ro.on_notice = [&hub](const nlohmann::json& j) {
    hub.publish_notice(j);
    if (j.value("type", "") == "run_end" || j.value("type", "") == "campaign_end") {
      spdlog::info("{} {}: {}{}", j.value("type", ""),
                   j.value("campaign", "") + (j.contains("run") ? "/" + j.value("run", "") : ""), j.value("outcome", ""),
                   j["reason"].is_string() ? " (" + j["reason"].get<std::string>() + ")" : "");
    }
  };
  CampaignRunner runner(std::move(ro));
  // The state on the stream and the operator link's rule (status_stream.hpp, operator_link.hpp).
  OperatorLink operator_link;
  api.on_request = [&operator_link] { operator_link.heard(); };
  StatusStream status_stream(runner, operator_link, [&hub](const nlohmann::json& j) { hub.publish_status(j); });
  ApiServer server(io, api, runner, hub);

  const std::string where = "http://" + (api.address.find(':') != std::string::npos ? "[" + api.address + "]" : api.address) +
                            ":" + std::to_string(server.port());
  std::printf("hilbench serve: listening on %s%s\n", where.c_str(), api.token.empty() ? "" : " (token required)");
  std::fflush(stdout);
  if (!args.port_file.empty()) {
    hil::replace_file(args.port_file, std::to_string(server.port()) + "\n");
  }

  boost::asio::signal_set signals(io, SIGINT, SIGTERM);
  std::thread waiter;
  std::function<void(const boost::system::error_code&, int)> on_signal = [&](const boost::system::error_code& ec, int sig) {
    if (ec) return;
    const std::string name = sig == SIGTERM ? "SIGTERM" : "SIGINT";
    if (waiter.joinable()) {
      spdlog::warn("{} again: still finishing the run (safe state, files); exiting as soon as it ends", name);
    } else {
      spdlog::warn("{} received: the running campaign goes to its safe state, then the server exits", name);
      server.refuse_starts("the server is shutting down (" + name + ")");
      server.cancel_jobs();  // a diagnosis stops at its next fit instead of holding the exit for minutes
      try {
        runner.abort(name + " received");
      } catch (const Conflict&) {  // idle
      }
      waiter = std::thread([&] {
        while (runner.running()) std::this_thread::sleep_for(std::chrono::milliseconds(10));
        boost::asio::post(io, [&] { io.stop(); });
      });
    }
    signals.async_wait(on_signal);
  };
  signals.async_wait(on_signal);
  // A handler that throws ends that handler's work, never the server: a campaign may be running.
  for (;;) {
    try {
      io.run();
      break;
    } catch (const std::exception& e) {
      spdlog::error("request handling: {} (the server goes on)", e.what());
    } catch (...) {
      spdlog::error("request handling: unknown exception (the server goes on)");
    }
  }
  if (waiter.joinable()) waiter.join();
  spdlog::info("hilbench serve: stopped");
  return 0;
}

}  // namespace

CommandRun define_serve(CLI::App& cmd) {
  auto args = std::make_shared<ServeArgs>();
  cmd.add_option("--listen", args->listen, "the operator API's address (port 0: any free one)")
      ->type_name("HOST:PORT")
      ->capture_default_str();
  cmd.add_option("--token", args->token, "the token every request must carry")->type_name("T")->envname("HILBENCH_TOKEN");
  cmd.add_option("--configs", args->configs_dir, "the folder holding campaigns/ and rigs/")
      ->type_name("DIR")
      ->capture_default_str();
  cmd.add_option("--runs-dir", args->runs_dir, "where runs are recorded")->type_name("DIR")->capture_default_str();
  cmd.add_option("--port-file", args->port_file, "write the port there once listening (the ready signal)")->type_name("F");
  cmd.add_option("--max-body-kb", args->max_body_kb, "the largest request body")
      ->type_name("N")
      ->check(whole_number(0, 1024 * 1024))
      ->capture_default_str();
  cmd.add_option("--max-waiting-jobs", args->max_waiting_jobs,
                 "reports and analyses that may wait for the job worker; more are refused (503)")
      ->type_name("N")
      ->check(whole_number(1, 1000))
      ->capture_default_str();
  cmd.add_option("--max-diagnose-mb", args->max_diagnose_mb,
                 "the most memory a diagnosis may hold (about twice its telemetry.csv); larger ones are refused "
                 "(422). Default: a quarter of this machine's memory")
      ->type_name("N")
      ->check(whole_number(1, std::int64_t{1} << 40));
  cmd.add_flag("--no-mlock", args->no_mlock, "do not lock the process's memory");
  cmd.add_option("--allow-host", args->allow_hosts,
                 "a host name (NAME, at the server's port, or NAME:PORT behind a proxy) requests may carry in Host and "
                 "Origin besides the listen address and 127.0.0.1, localhost, [::1]; repeatable. Any other is refused "
                 "(403): DNS rebinding")
      ->type_name("NAME")
      ->take_all();
  cmd.add_option("--ws-idle-timeout-s", args->ws_idle_timeout_s,
                 "a telemetry WebSocket that sends nothing for this long, not even the answer to the server's ping "
                 "(sent at half this time), is closed; a client that reads answers pings")
      ->type_name("S")
      ->check(CLI::Range(0.2, 86400.0))
      ->capture_default_str();
  return [args] { return run_serve(*args); };
}

}  // namespace hil::bench
