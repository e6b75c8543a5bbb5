// hilbench ctl [--server URL] [--token T] COMMAND ...: the command-line client of hilbench serve.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <thread>

#include "cli.hpp"
#include "commands.hpp"
#include "hil/bench/api_client.hpp"
#include "hil/bench/runner.hpp"

namespace hil::bench {
namespace {

using nlohmann::json;

constexpr const char* kCtlHelp =
    "hilbench ctl [--server URL] [--token T] COMMAND\n"
    "  URL defaults to $HILBENCH_SERVER or http://127.0.0.1:8470; T to $HILBENCH_TOKEN\n"
    "commands:\n"
    "  status [--json]                       state, progress, loop statistics, active faults\n"
    "  campaigns | rigs | runs               what the server offers / has recorded\n"
    "  start NAME|FILE.yaml [--rig R] [--runs a,b] [--speed X] [--detach]\n"
    "                                        start a campaign (a name, or a YAML file posted) and\n"
    "                                        follow it with a progress bar unless --detach\n"
    "  watch                                 progress bar of the running campaign until it ends\n"
    "  stop                                  end the campaign now (outcome 'stopped')\n"
    "  abort [--reason TEXT]                 safe state, then end (outcome 'aborted')\n"
    "  inject gap DEG | inject gap programme the true gap now / back to the campaign's programme\n"
    "  inject sensor stuck|dropout [--duration-s S]\n"
    "  inject sensor bias KPA|noise KPA [--duration-s S]\n"
    "  inject drive [--off] [--duration-s S] the drive ignores commands\n"
    "  inject rig silent [--off]             the (simulated) rig stops answering\n"
    "  inject clear                          clear every fault\n"
    "  telemetry [--rate-hz N] [--count N]   live rows as CSV on stdout\n"
    "  show RUN                              a past run's run.json and files\n"
    "  get RUN FILE [--out PATH]             download a file of a past run\n"
    "exit status: 0 success (a followed campaign completed), 1 error reply or failure,\n"
    "             2 usage, 3 a followed campaign ended stopped, aborted or in error";

[[noreturn]] void fail(const ApiReply& r) {
  std::string error = "HTTP " + std::to_string(r.status), detail;
  try {
    const json j = r.json();
    error = j.value("error", error);
    detail = j.value("detail", "");
  } catch (const std::exception&) {
    detail = r.body.substr(0, 300);
  }
  throw std::runtime_error(error + (detail.empty() ? "" : ": " + detail) + " (HTTP " + std::to_string(r.status) + ")");
}

json checked(const ApiReply& r) {
  if (!r.ok()) fail(r);
  return r.json();
}

std::string clock(double s) {
  if (!std::isfinite(s) || s < 0) s = 0;
  const long t = std::lround(s);
  char buf[32];
  std::snprintf(buf, sizeof buf, "%ld:%02ld", t / 60, t % 60);
  return buf;
}

std::string number(const json& j, const char* fmt_spec, const char* fallback = "-") {
  if (!j.is_number()) return fallback;
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt_spec, j.get<double>());
  return buf;
}

void print_last(const json& last) {
  if (last.is_null()) return;
  std::printf("last campaign: %s on %s: %s%s\n", last.value("campaign", "?").c_str(), last.value("rig", "?").c_str(),
              last.value("outcome", "?").c_str(), last["reason"].is_string() ? (" (" + last["reason"].get<std::string>() + ")").c_str() : "");
  for (const auto& r : last.value("runs", json::array())) {
    std::printf("  %-12s %-10s %s\n", r.value("run", "?").c_str(), r.value("outcome", "?").c_str(), r.value("dir", "").c_str());
  }
}

void print_status(const json& s) {
  const std::string state = s.value("state", "?");
  if (state == "idle") {
    std::printf("idle\n");
    print_last(s["last"]);
    return;
  }
  const json& p = s["progress"];
  std::printf("%s: campaign %s (%s) on rig %s, run %s (%d of %d), speed %gx\n", state.c_str(), s.value("campaign", "?").c_str(),
              s.value("source", "?").c_str(), s.value("rig", "?").c_str(), s.value("run", "?").c_str(),
              s.value("run_index", 0) + 1, s.value("runs_total", 0), s.value("speed", 1.0));
  std::printf("  progress %s%%  t = %s of %s s  elapsed %s  remaining %s\n", number(p["fraction"].get<double>() * 100, "%.1f").c_str(),
              number(p["t_s"], "%.2f").c_str(), number(p["duration_s"], "%.1f").c_str(), clock(p.value("elapsed_s", 0.0)).c_str(),
              clock(p.value("remaining_s", 0.0)).c_str());
  if (s.contains("loop")) {
    const json& l = s["loop"];
    const json& w = l["wake_latency_us"];
    const json& c = l["compute_us"];
    std::printf("  loop %s%s: %lld periods, %lld overruns, %lld missed reads\n", l.value("sched", "").c_str(),
                l.value("memory_locked", false) ? ", memory locked" : "", l.value("periods", 0LL), l.value("overruns", 0LL),
                l.value("missed_reads", 0LL));
    std::printf("  wake-up latency us: min %s mean %s p99 %s p99.9 %s max %s\n", number(w["min_us"], "%.1f").c_str(),
                number(w["mean_us"], "%.1f").c_str(), number(w["p99_us"], "%.1f").c_str(), number(w["p99_9_us"], "%.1f").c_str(),
                number(w["max_us"], "%.1f").c_str());
    std::printf("  compute us:         min %s mean %s p99 %s p99.9 %s max %s\n", number(c["min_us"], "%.1f").c_str(),
                number(c["mean_us"], "%.1f").c_str(), number(c["p99_us"], "%.1f").c_str(), number(c["p99_9_us"], "%.1f").c_str(),
                number(c["max_us"], "%.1f").c_str());
    if (!l.value("rt_warning", "").empty()) std::printf("  warning: %s\n", l.value("rt_warning", "").c_str());
  }
  if (s.contains("now")) {
    const json& n = s["now"];
    std::printf("  now: p_meas %s MPa, p_ref %s MPa, cmd %s deg, gap %s deg\n", number(n["p_meas_mpa"], "%.4f").c_str(),
                number(n["p_ref_mpa"], "%.4f").c_str(), number(n["theta_cmd_deg"], "%.3f").c_str(),
                number(n["gap_true_deg"], "%.3f").c_str());
  }
  if (s.contains("telemetry")) {
    const json& t = s["telemetry"];
    std::printf("  telemetry: %llu rows on disk; not recorded: %llu rows (ring full), %llu rows (disk), %llu events%s\n",
                t.value("rows_written", 0ULL), t.value("rows_lost", 0ULL), t.value("rows_unwritten", 0ULL), t.value("events_lost", 0ULL),
                t.value("write_error", json(nullptr)).is_string() ? "  DISK REFUSED TELEMETRY" : "");
  }
  if (s.contains("safety") && s["safety"].value("safe_state", false)) {
    std::printf("  SAFE STATE (trip: %s)\n", s["safety"]["trip"].is_string() ? s["safety"]["trip"].get<std::string>().c_str() : "?");
  }
  for (const auto& f : s.value("faults", json::array())) std::printf("  fault: %s\n", f.dump().c_str());
}

// Follows the running campaign with a progress bar; returns the exit status of its outcome.
int watch(const ApiClient& api) {
  const bool tty = ::isatty(STDERR_FILENO);
  int last_decile = -1;
  std::string last_run;
  for (;;) {
    const json s = checked(api.get("/api/status"));
    if (s.value("state", "") == "idle") {
      if (tty) std::fprintf(stderr, "\n");
      print_last(s["last"]);
      const std::string outcome = s["last"].is_object() ? s["last"].value("outcome", "") : "";
      return outcome_from(outcome) == Outcome::completed ? 0 : 3;
    }
    const json& p = s["progress"];
    const double f = std::clamp(p.value("fraction", 0.0), 0.0, 1.0);
    const std::string run = s.value("run", "?");
    constexpr int kWidth = 30;
    const int filled = static_cast<int>(f * kWidth);
    std::string bar(static_cast<std::size_t>(filled), '#');
    bar.resize(kWidth, '.');
    const std::string faults = s.value("faults", json::array()).empty() ? "" : "  faults " + std::to_string(s["faults"].size());
    const std::string safe = s.value("state", "") == "safe" ? "  SAFE STATE" : "";
    char line[300];
    std::snprintf(line, sizeof line, "[%s] %3.0f%%  %s %s (%d/%d)  t %5.1f/%.0f s  elapsed %s  remaining %s  lost %llu%s%s",
                  bar.c_str(), f * 100, s.value("campaign", "?").c_str(), run.c_str(), s.value("run_index", 0) + 1,
                  s.value("runs_total", 0), p.value("t_s", 0.0), p.value("duration_s", 0.0), clock(p.value("elapsed_s", 0.0)).c_str(),
                  clock(p.value("remaining_s", 0.0)).c_str(),
                  s.contains("telemetry") ? s["telemetry"].value("rows_lost", 0ULL) + s["telemetry"].value("rows_unwritten", 0ULL) : 0ULL,
                  faults.c_str(), safe.c_str());
    const int decile = static_cast<int>(f * 10);
    if (tty) {
      std::fprintf(stderr, "\r%s\033[K", line);
    } else if (decile != last_decile || run != last_run) {
      std::fprintf(stderr, "%s\n", line);
    }
    last_decile = decile;
    last_run = run;
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

int cmd_ctl(const std::vector<std::string>& argv) {
  const Args args = parse_args(argv, {"server", "token", "rig", "runs", "speed", "reason", "duration-s", "rate-hz", "count", "out"},
                               {"detach", "json", "off", "help"});
  if (args.has("help")) {
    std::printf("%s\n", kCtlHelp);
    return 0;
  }
  if (args.positional.empty()) throw UsageError(std::string("ctl needs a command\n") + kCtlHelp);
  const char* env_server = std::getenv("HILBENCH_SERVER");
  const char* env_token = std::getenv("HILBENCH_TOKEN");
  const ApiClient api(args.option("server", env_server ? env_server : "http://127.0.0.1:8470"),
                      args.option("token", env_token ? env_token : ""));
  const auto& pos = args.positional;
  const std::string& cmd = pos[0];
  auto need = [&](std::size_t n, const char* usage) {
    if (pos.size() != n) throw UsageError(std::string("usage: hilbench ctl ") + usage);
  };

  if (cmd == "status") {
    need(1, "status [--json]");
    const json s = checked(api.get("/api/status"));
    if (args.has("json")) {
      std::printf("%s\n", s.dump(2).c_str());
    } else {
      print_status(s);
    }
    return 0;
  }
  if (cmd == "campaigns" || cmd == "rigs") {
    need(1, "campaigns | rigs");
    const json j = checked(api.get("/api/" + cmd));
    for (const auto& c : j[cmd]) {
      if (c.contains("error")) {
        std::printf("%-20s ERROR %s\n", c.value("name", "?").c_str(), c.value("error", "").c_str());
      } else if (cmd == "campaigns") {
        std::string runs;
        for (const auto& r : c["runs"]) runs += (runs.empty() ? std::string() : std::string(",")) + r.get<std::string>();
        std::printf("%-20s %6.1f s  dT %g ms  runs %-20s %s\n", c.value("name", "?").c_str(), c.value("duration_s", 0.0),
                    c.value("period_ms", 0.0), runs.c_str(), c.value("description", "").c_str());
      } else {
        std::printf("%-20s %-8s prio %-3d cpu %-3d %s\n", c.value("name", "?").c_str(), c.value("kind", "?").c_str(),
                    c.value("priority", 0), c.value("cpu", -1), c.value("description", "").c_str());
      }
    }
    return 0;
  }
  if (cmd == "runs") {
    need(1, "runs");
    const json list = checked(api.get("/api/runs"));
    for (const auto& r : list["runs"]) {
      std::printf("%-50s %-10s %s\n", r.value("id", "?").c_str(), r["outcome"].is_string() ? r["outcome"].get<std::string>().c_str() : "?",
                  r["reason"].is_string() ? r["reason"].get<std::string>().c_str() : "");
    }
    return 0;
  }
  if (cmd == "start") {
    need(2, "start NAME|FILE.yaml [--rig R] [--runs a,b] [--speed X] [--detach]");
    json body = {{"rig", args.option("rig", "sim")}};
    const std::string& what = pos[1];
    const bool file = what.find('/') != std::string::npos || what.ends_with(".yaml") || what.ends_with(".yml");
    if (file) {
      body["campaign_yaml"] = read_file(what);
    } else {
      body["campaign"] = what;
    }
    if (args.options.count("runs")) {
      std::stringstream rs(args.option("runs", ""));
      body["runs"] = json::array();
      for (std::string r; std::getline(rs, r, ',');) {
        if (!r.empty()) body["runs"].push_back(r);
      }
    }
    if (args.options.count("speed")) body["speed"] = parse_number(args.option("speed", "1"), "--speed");
    const json j = checked(api.post("/api/start", body));
    std::printf("started %s on %s\n", j.value("started", "?").c_str(), j.value("rig", "?").c_str());
    std::fflush(stdout);
    return args.has("detach") ? 0 : watch(api);
  }
  if (cmd == "watch") {
    need(1, "watch");
    return watch(api);
  }
  if (cmd == "stop") {
    need(1, "stop");
    checked(api.post("/api/stop", json::object()));
    std::printf("stopping\n");
    return 0;
  }
  if (cmd == "abort") {
    need(1, "abort [--reason TEXT]");
    const json j = checked(api.post("/api/abort", {{"reason", args.option("reason", "from hilbench ctl")}}));
    std::printf("aborting (%s)\n", j.value("reason", "").c_str());
    return 0;
  }
  if (cmd == "inject") {
    if (pos.size() < 2) throw UsageError("usage: hilbench ctl inject gap|sensor|drive|rig|clear ...");
    const std::string& kind = pos[1];
    json body = json::object();
    if (args.options.count("duration-s")) body["duration_s"] = parse_number(args.option("duration-s", "0"), "--duration-s");
    if (kind == "gap") {
      need(3, "inject gap DEG | inject gap programme");
      body.erase("duration_s");
      if (pos[2] == "programme" || pos[2] == "program") {
        body["programme"] = true;
      } else {
        body["gap_deg"] = parse_number(pos[2], "the gap");
      }
    } else if (kind == "sensor") {
      if (pos.size() < 3) throw UsageError("usage: hilbench ctl inject sensor stuck|dropout|bias KPA|noise KPA [--duration-s S]");
      body["mode"] = pos[2];
      if (pos[2] == "bias" || pos[2] == "noise") {
        need(4, "inject sensor bias KPA|noise KPA [--duration-s S]");
        body[pos[2] == "bias" ? "bias_kpa" : "rms_kpa"] = parse_number(pos[3], "the size in kPa");
      } else {
        need(3, "inject sensor stuck|dropout [--duration-s S]");
      }
    } else if (kind == "drive") {
      need(2, "inject drive [--off] [--duration-s S]");
      body["mode"] = "ignore_commands";
      body["on"] = !args.has("off");
    } else if (kind == "rig") {
      need(3, "inject rig silent [--off]");
      body["mode"] = pos[2];
      body["on"] = !args.has("off");
      body.erase("duration_s");
    } else if (kind == "clear") {
      need(2, "inject clear");
      body = json::object();
    } else {
      throw UsageError("inject what? gap, sensor, drive, rig or clear");
    }
    checked(api.post("/api/inject/" + kind, body));
    std::printf("injected %s %s\n", kind.c_str(), body.dump().c_str());
    return 0;
  }
  if (cmd == "telemetry") {
    need(1, "telemetry [--rate-hz N] [--count N]");
    const double rate = parse_number(args.option("rate-hz", "10"), "--rate-hz");
    const long count = std::lround(parse_number(args.option("count", "0"), "--count"));
    std::vector<std::string> columns;
    long rows = 0;
    char target[64];
    std::snprintf(target, sizeof target, "/api/telemetry?rate_hz=%g", rate);
    api.stream(target, [&](const std::string& message) {
      const json j = json::parse(message);
      const std::string type = j.value("type", "");
      if (type == "hello") {
        for (const auto& c : j["columns"]) columns.push_back(c.get<std::string>());
        std::string header;
        for (const auto& c : columns) header += (header.empty() ? std::string() : std::string(",")) + c;
        std::printf("%s\n", header.c_str());
      } else if (type == "row") {
        std::string line;
        for (const auto& c : columns) {
          if (!line.empty()) line.push_back(',');
          line += j[c].is_number() ? number(j[c], "%.6g") : std::string("nan");
        }
        std::printf("%s\n", line.c_str());
        ++rows;
      } else {
        std::printf("# %s\n", message.c_str());
      }
      std::fflush(stdout);
      return count <= 0 || rows < count;
    });
    return 0;
  }
  if (cmd == "show") {
    need(2, "show RUN");
    std::printf("%s\n", checked(api.get("/api/runs/" + pos[1])).dump(2).c_str());
    return 0;
  }
  if (cmd == "get") {
    need(3, "get RUN FILE [--out PATH]");
    const std::filesystem::path out = args.option("out", pos[2]);
    const ApiReply r = api.download("/api/runs/" + pos[1] + "/" + pos[2], out);
    if (!r.ok()) fail(r);
    std::printf("%s (%ju bytes)\n", out.c_str(), static_cast<std::uintmax_t>(std::filesystem::file_size(out)));
    return 0;
  }
  throw UsageError("unknown ctl command '" + cmd + "'\n" + kCtlHelp);
}

}  // namespace hil::bench
