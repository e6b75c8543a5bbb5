// hilbench ctl [--server URL] [--token T] COMMAND ...: the command-line client of hilbench serve.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <thread>

#include <spdlog/spdlog.h>

#include "commands.hpp"
#include "ctl_junit.hpp"
#include "hil/bench/server/api_client.hpp"
#include "hil/bench/server/runner.hpp"
#include "hil/config.hpp"
#include "hil/output_path.hpp"
#include "hil/progress_line.hpp"
#include "hil/text_file.hpp"

namespace hil::bench {
namespace {

using nlohmann::json;

// An error reply as one line: the server's error and detail, and the request field it blamed.
[[noreturn]] void fail(const ApiReply& r) {
  std::string error = "HTTP " + std::to_string(r.status), detail, field;
  try {
    const json j = r.json();
    error = j.value("error", error);
    detail = j.value("detail", "");
    field = j.value("field", "");
  } catch (const std::exception&) {
    detail = r.body;
  }
  // What the peer sent goes to a terminal: its control bytes shown, not obeyed.
  throw std::runtime_error(printable(error, 200) + (field.empty() ? "" : " (field '" + printable(field, 100) + "')") +
                           (detail.empty() ? "" : ": " + printable(detail, 300)) + " (HTTP " + std::to_string(r.status) + ")");
}

json checked(const ApiReply& r) {
  if (!r.ok()) fail(r);
  return r.json();
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
              last.value("outcome", "?").c_str(),
              last["reason"].is_string() ? (" (" + last["reason"].get<std::string>() + ")").c_str() : "");
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
  std::printf("  progress %s%%  t = %s of %s s  elapsed %s  remaining %s\n",
              number(p["fraction"].get<double>() * 100, "%.1f").c_str(), number(p["t_s"], "%.2f").c_str(),
              number(p["duration_s"], "%.1f").c_str(), duration_text(p.value("elapsed_s", 0.0)).c_str(),
              duration_text(p.value("remaining_s", 0.0)).c_str());
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
                t.value("rows_written", 0ULL), t.value("rows_lost", 0ULL), t.value("rows_unwritten", 0ULL),
                t.value("events_lost", 0ULL),
                t.value("write_error", json(nullptr)).is_string() ? "  DISK REFUSED TELEMETRY" : "");
  }
  if (s.contains("safety") && s["safety"].value("safe_state", false)) {
    std::printf("  SAFE STATE (trip: %s)\n",
                s["safety"]["trip"].is_string() ? s["safety"]["trip"].get<std::string>().c_str() : "?");
  }
  for (const auto& f : s.value("faults", json::array())) std::printf("  fault: %s\n", f.dump().c_str());
}

// Follows the running campaign with hil::ProgressLine (redrawn in place on a terminal, a line a
// tenth in a log) until it ends; returns the exit status of its outcome.
int watch(const ApiClient& api) {
  std::optional<ProgressLine> line;
  for (;;) {
    const json s = checked(api.get("/api/status"));
    if (s.value("state", "") == "idle") {
      if (line) line->end();
      print_last(s["last"]);
      const std::string outcome = s["last"].is_object() ? s["last"].value("outcome", "") : "";
      return outcome_from(outcome) == Outcome::completed ? 0 : 3;
    }
    const json& p = s["progress"];
    const double f = p.value("fraction", 0.0);
    if (!line) {
      ProgressLine::Options o;
      o.start_fraction = f;  // joined part way: the ETA is from the rate seen here
      line.emplace(s.value("campaign", "?"), o);
    }
    line->update(f, [&] {
      const auto& t = s.contains("telemetry") ? s["telemetry"] : json::object();
      const auto faults = s.value("faults", json::array()).size();
      return s.value("run", "?") + " (" + std::to_string(s.value("run_index", 0) + 1) + "/" +
             std::to_string(s.value("runs_total", 0)) + "), t " + number(p.value("t_s", 0.0), "%.1f") + "/" +
             number(p.value("duration_s", 0.0), "%.0f") + " s, rows not recorded " +
             std::to_string(t.value("rows_lost", 0ULL) + t.value("rows_unwritten", 0ULL)) +
             (faults > 0 ? ", faults " + std::to_string(faults) : "") + (s.value("state", "") == "safe" ? ", SAFE STATE" : "");
    });
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
}

// A member of a JSON object, null when absent (a const json's operator[] must not be asked for a
// key it lacks).
json member(const json& j, const char* key) { return j.is_object() && j.contains(key) ? j[key] : json(nullptr); }

// An analysis's headline: compare's fit against the noise floor, diagnose's verdict and what it
// added; a failure's reason; the progress while it runs.
std::string analysis_headline(const json& a) {
  const std::string state = a.value("state", "?");
  if (state == "failed") return a.value("error", "");
  const json r = member(a, "result");
  if (state != "done" || !r.is_object()) {
    const json p = member(a, "progress");
    return p.is_number() ? number(p.get<double>() * 100, "%.0f %%") : "";
  }
  if (a.value("kind", "") == "diagnose") {
    std::string added;
    for (const auto& e : r.value("added", json::array())) {
      added += (added.empty() ? "" : ", ") + e.value("effect", "?") + " (" + e.value("variant", "?") + ")";
    }
    return "verdict " + r.value("verdict", "?") + ", fit " + number(member(r, "fit_before_pct"), "%.2f") + " % -> " +
           number(member(r, "fit_after_pct"), "%.2f") + " % (noise floor " + number(member(r, "noise_floor_fit_pct"), "%.2f") +
           " %)" + (added.empty() ? "" : "; added " + added);
  }
  return "fit " + number(member(r, "fit_pct"), "%.2f") + " % (noise floor " + number(member(r, "noise_floor_fit_pct"), "%.2f") +
         " %), RMSE " + number(member(r, "rmse_kpa"), "%.3g") + " kPa, largest error " +
         number(member(r, "max_error_kpa"), "%.3g") + " kPa at " + number(member(r, "max_error_t_s"), "%.4g") + " s";
}

// ctl's command line: the server every command talks to, and each command's arguments (one
// command runs, so commands that share an option share its field).
struct CtlArgs {
  std::string server_url = "http://127.0.0.1:8470";
  std::string token;
  bool json = false;                        // status
  std::string campaign, rig = "sim", runs;  // start
  const CLI::Option* runs_opt = nullptr;    // start: given (even empty: refused, never "every run")
  double speed = 1;                         // start, given or not (speed_opt)
  const CLI::Option* speed_opt = nullptr;
  bool detach = false;                       // start
  std::string junit;                         // start: the verdicts as JUnit XML; empty: none
  std::string reason = "from hilbench ctl";  // abort
  std::string gap;                           // inject gap: DEG or "programme"
  std::string mode;                          // inject sensor / rig
  double size_kpa = std::nan("");            // inject sensor bias|noise; NaN: not given
  double duration_s = std::nan("");          // inject sensor / drive; NaN: until cleared
  bool off = false;                          // inject drive / rig
  double rate_hz = 10;                       // telemetry
  long count = 0;                            // telemetry; 0: until the stream ends
  std::string run, file, out;                // show, get, analyse, analyses
  std::string kind, model;                   // analyse
  bool wait = false;                         // analyse
};

using Handler = std::function<int(const CtlArgs&, const ApiClient&)>;

int inject(const std::string& kind, json body, const ApiClient& api) {
  checked(api.post("/api/inject/" + kind, body));
  std::printf("injected %s %s\n", kind.c_str(), body.dump().c_str());
  return 0;
}

int start(const CtlArgs& a, const ApiClient& api) {
  json body = {{"rig", a.rig}};
  const bool file = a.campaign.find('/') != std::string::npos || a.campaign.ends_with(".yaml") || a.campaign.ends_with(".yml");
  // Before anything starts: a --junit the campaign could not end into is said now, not after it.
  if (!a.junit.empty())
    check_junit_output(a.junit, file ? std::vector<std::filesystem::path>{a.campaign} : std::vector<std::filesystem::path>{});
  if (file) {
    body["campaign_yaml"] = hil::read_text_file(a.campaign, "a campaign file");
  } else {
    body["campaign"] = a.campaign;
  }
  if (a.runs_opt->count() > 0) body["runs"] = run_names(a.runs);
  if (a.speed_opt->count() > 0) body["speed"] = a.speed;
  const json j = checked(api.post("/api/start", body));
  std::printf("started %s on %s\n", j.value("started", "?").c_str(), j.value("rig", "?").c_str());
  if (j.contains("warning")) std::printf("warning: %s\n", j.value("warning", "").c_str());
  std::fflush(stdout);
  if (a.detach) return 0;
  const int rc = watch(api);
  if (a.junit.empty()) return rc;
  // The verdicts the server's checks gave on the rig; a failed check fails the command (3), as
  // in `hilbench sim --junit`.
  const long failed = write_served_junit(checked(api.get("/api/status"))["last"], a.junit);
  if (failed > 0) std::printf("%ld check(s) failed; JUnit XML: %s\n", failed, a.junit.c_str());
  return failed > 0 ? 3 : rc;
}

// Posts an analysis of a run; with --wait follows it to the end: the headline and the report's URL,
// or the server's reason for the failure (exit 3).
int analyse(const CtlArgs& a, const ApiClient& api) {
  const std::string base = "/api/runs/" + a.run + "/analyses";
  const json posted = checked(api.post(base, {{"kind", a.kind}, {"model", a.model}}));
  json job = posted.value("analysis", json::object());
  const std::string id = job.value("id", "?");
  std::printf("%s: %s of %s against %s, %s%s\n", id.c_str(), a.kind.c_str(), a.run.c_str(), a.model.c_str(),
              job.value("state", "?").c_str(), posted.contains("note") ? (" (" + posted.value("note", "") + ")").c_str() : "");
  std::fflush(stdout);
  if (!a.wait) return 0;
  std::string last_line;
  for (;;) {
    const std::string state = job.value("state", "?");
    if (state == "done" || state == "failed") break;
    const std::string line = state + (member(job, "progress").is_number() ? " " + analysis_headline(job) : "");
    if (line != last_line) spdlog::info("{}: {}", id, line);
    last_line = line;
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
    job = checked(api.get(base + "/" + id)).value("analysis", json::object());
  }
  if (job.value("state", "") == "failed") {
    spdlog::error("{} failed: {}", id, job.value("error", ""));
    return 3;
  }
  std::printf("%s done: %s\n", id.c_str(), analysis_headline(job).c_str());
  if (member(job, "result").is_object()) {
    for (const auto& line : job["result"].value("summary", json::array())) {
      if (line.is_string()) std::printf("  %s\n", line.get<std::string>().c_str());
    }
  }
  std::printf("report: http://%s:%s%s\n", api.host().c_str(), api.port().c_str(), job.value("report", "").c_str());
  return 0;
}

int telemetry(const CtlArgs& a, const ApiClient& api) {
  std::vector<std::string> columns;
  long rows = 0;
  std::string last_state;
  char rate[32];
  std::snprintf(rate, sizeof rate, "%g", a.rate_hz);
  // %g writes 1e+06; a '+' in a query is a space (the server answered "got '1e 06'").
  std::string target = "/api/telemetry?rate_hz=";
  for (const char* c = rate; *c != '\0'; ++c) target += *c == '+' ? std::string("%2B") : std::string(1, *c);
  const auto on_message = [&](const std::string& message) {
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
    } else if (type == "status") {  // the server's heartbeat, twice a second: a line only when the state changes
      const std::string state = j.value("state", "");
      if (state == last_state) return true;
      last_state = state;
      std::printf("# %s\n", message.c_str());
    } else {
      std::printf("# %s\n", message.c_str());
    }
    std::fflush(stdout);
    return a.count <= 0 || rows < a.count;
  };
  try {
    api.stream(target, on_message);
  } catch (const ApiRefused& e) {
    fail(e.reply());  // the server's status, error and detail, as any other command says them
  }
  return 0;
}

// The commands of `hilbench ctl`, each with its arguments and what it does.
void define_commands(CLI::App& ctl, CtlArgs& args, std::vector<std::pair<const CLI::App*, Handler>>& handlers) {
  const auto command = [&](CLI::App& parent, const std::string& name, const std::string& summary, Handler h = nullptr) {
    CLI::App* cmd = add_command(parent, name, summary);
    if (h) handlers.emplace_back(cmd, std::move(h));
    return cmd;
  };
  command(ctl, "status", "state, progress, loop statistics, active faults", [](const CtlArgs& a, const ApiClient& api) {
    const json s = checked(api.get("/api/status"));
    if (a.json) {
      std::printf("%s\n", s.dump(2).c_str());
    } else {
      print_status(s);
    }
    return 0;
  })->add_flag("--json", args.json, "the server's answer as JSON");
  for (const std::string what : {"campaigns", "rigs"}) {
    command(ctl, what, "what the server offers: its " + what, [what](const CtlArgs&, const ApiClient& api) {
      const json j = checked(api.get("/api/" + what));
      for (const auto& c : j[what]) {
        if (c.contains("error")) {
          std::printf("%-20s ERROR %s\n", c.value("name", "?").c_str(), c.value("error", "").c_str());
        } else if (what == "campaigns") {
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
    });
  }
  command(ctl, "runs", "the runs the server has recorded", [](const CtlArgs&, const ApiClient& api) {
    const json list = checked(api.get("/api/runs"));
    for (const auto& r : list["runs"]) {
      std::printf("%-50s %-10s %s\n", r.value("id", "?").c_str(),
                  r["outcome"].is_string() ? r["outcome"].get<std::string>().c_str() : "?",
                  r["reason"].is_string() ? r["reason"].get<std::string>().c_str() : "");
    }
    return 0;
  });

  CLI::App* s = command(ctl, "start", "start a campaign (a name, or a YAML file posted); follow it with a progress bar", start);
  s->add_option("campaign", args.campaign, "the campaign's name on the server, or a campaign file")
      ->required()
      ->type_name("NAME|FILE.yaml");
  s->add_option("--rig", args.rig, "the rig it runs on")->type_name("R")->capture_default_str();
  args.runs_opt = s->add_option("--runs", args.runs, "only these runs of the campaign")->type_name("a,b");
  args.speed_opt =
      s->add_option("--speed", args.speed, "the simulated rig's speed, times real time")->type_name("X")->check(finite_number());
  CLI::Option* detach = s->add_flag("--detach", args.detach, "return once started, no progress bar");
  s->add_option("--junit", args.junit, "once it ends, its checks' verdicts as JUnit XML (exit 3 when one failed)")
      ->type_name("FILE")
      ->excludes(detach);

  command(ctl, "watch", "progress bar of the running campaign until it ends",
          [](const CtlArgs&, const ApiClient& api) { return watch(api); });
  command(ctl, "stop", "end the campaign now (outcome 'stopped')", [](const CtlArgs&, const ApiClient& api) {
    checked(api.post("/api/stop", json::object()));
    std::printf("stopping\n");
    return 0;
  });
  command(ctl, "abort", "safe state, then end (outcome 'aborted')",
          [](const CtlArgs& a, const ApiClient& api) {
            const json j = checked(api.post("/api/abort", {{"reason", a.reason}}));
            std::printf("aborting (%s)\n", j.value("reason", "").c_str());
            return 0;
          })
      ->add_option("--reason", args.reason, "why, for the run's record")
      ->type_name("TEXT");

  CLI::App* in = command(ctl, "inject", "faults into the running campaign: gap, sensor, drive, rig; clear them");
  in->require_subcommand(1);
  command(*in, "gap", "the true gap now, deg, or back to the campaign's programme",
          [](const CtlArgs& a, const ApiClient& api) {
            const bool programme = a.gap == "programme" || a.gap == "program";
            return inject("gap", programme ? json{{"programme", true}} : json{{"gap_deg", std::stod(a.gap)}}, api);
          })
      ->add_option("gap", args.gap, "degrees, or 'programme'")
      ->required()
      ->type_name("DEG|programme")
      ->check(CLI::Validator(
          [](std::string& text) {
            if (text == "programme" || text == "program") return std::string();
            return finite_number()(text).empty() ? std::string() : "needs degrees or 'programme', got '" + text + "'";
          },
          ""));
  CLI::App* sensor =
      command(*in, "sensor", "stuck, dropout, or a bias or noise of KPA", [](const CtlArgs& a, const ApiClient& api) {
        const bool sized = a.mode == "bias" || a.mode == "noise";
        if (sized && std::isnan(a.size_kpa)) throw UsageError("sensor " + a.mode + " needs its size, KPA");
        if (!sized && !std::isnan(a.size_kpa)) throw UsageError("sensor " + a.mode + " takes no size");
        json body = {{"mode", a.mode}};
        if (sized) body[a.mode == "bias" ? "bias_kpa" : "rms_kpa"] = a.size_kpa;
        if (!std::isnan(a.duration_s)) body["duration_s"] = a.duration_s;
        return inject("sensor", body, api);
      });
  // The kinds are in the type name already: the check's own description would repeat them.
  sensor->add_option("mode", args.mode, "the fault")
      ->required()
      ->type_name("stuck|dropout|bias|noise")
      ->check(CLI::IsMember({"stuck", "dropout", "bias", "noise"}).description(""));
  sensor->add_option("size", args.size_kpa, "the bias or the noise RMS, kPa")->type_name("KPA")->check(finite_number());
  sensor->add_option("--duration-s", args.duration_s, "how long (default: until cleared)")
      ->type_name("S")
      ->check(non_negative_number());
  CLI::App* drive = command(*in, "drive", "the drive ignores commands", [](const CtlArgs& a, const ApiClient& api) {
    json body = {{"mode", "ignore_commands"}, {"on", !a.off}};
    if (!std::isnan(a.duration_s)) body["duration_s"] = a.duration_s;
    return inject("drive", body, api);
  });
  drive->add_flag("--off", args.off, "end the fault");
  drive->add_option("--duration-s", args.duration_s, "how long (default: until cleared)")
      ->type_name("S")
      ->check(non_negative_number());
  CLI::App* rig = command(*in, "rig", "the (simulated) rig stops answering", [](const CtlArgs& a, const ApiClient& api) {
    return inject("rig", {{"mode", a.mode}, {"on", !a.off}}, api);
  });
  rig->add_option("mode", args.mode, "the fault")
      ->required()
      ->type_name("silent")
      ->check(CLI::IsMember({"silent"}).description(""));
  rig->add_flag("--off", args.off, "end the fault");
  command(*in, "clear", "clear every fault",
          [](const CtlArgs&, const ApiClient& api) { return inject("clear", json::object(), api); });

  CLI::App* t = command(ctl, "telemetry", "live rows as CSV on stdout", telemetry);
  t->add_option("--rate-hz", args.rate_hz, "rows per second")->type_name("N")->check(finite_number())->capture_default_str();
  t->add_option("--count", args.count, "stop after N rows (0: never)")->type_name("N")->check(whole_number(0, INT64_MAX));

  command(ctl, "show", "a past run's run.json and files",
          [](const CtlArgs& a, const ApiClient& api) {
            std::printf("%s\n", checked(api.get("/api/runs/" + a.run)).dump(2).c_str());
            return 0;
          })
      ->add_option("run", args.run, "the run's id (hilbench ctl runs)")
      ->required()
      ->type_name("RUN");
  CLI::App* get = command(ctl, "get", "download a file of a past run", [](const CtlArgs& a, const ApiClient& api) {
    // FILE may be a path in the run (analyses/AID/report.html); what is written is its last part.
    const std::filesystem::path out = a.out.empty() ? std::filesystem::path(a.file).filename() : std::filesystem::path(a.out);
    if (out.empty()) throw UsageError("'" + a.file + "' names no file; --out says where it goes");
    check_output_file("--out", out, {}, "the download");
    const ApiReply r = api.download("/api/runs/" + a.run + "/" + a.file, out);
    if (r.status == 202) {
      const std::string state = r.json().value("analysis", json::object()).value("state", "in flight");
      throw std::runtime_error("the analysis is " + state + "; nothing to download yet (hilbench ctl analyses " + a.run + ")");
    }
    if (!r.ok()) fail(r);
    std::printf("%s (%ju bytes)\n", out.c_str(), static_cast<std::uintmax_t>(std::filesystem::file_size(out)));
    return 0;
  });
  get->add_option("run", args.run, "the run's id (hilbench ctl runs)")->required()->type_name("RUN");
  get->add_option("file", args.file, "the file's name in the run, or analyses/AID/FILE of an analysis")
      ->required()
      ->type_name("FILE");
  get->add_option("--out", args.out, "where it goes (default: FILE's name, in the current folder)")
      ->type_name("PATH")
      ->check(path_value());

  // The kind is checked by the server (GET /api/models lists the kinds it has).
  CLI::App* an = command(ctl, "analyse", "compare or diagnose an ended run against a plant model of the server", analyse);
  an->add_option("run", args.run, "the run's id (hilbench ctl runs)")->required()->type_name("RUN");
  an->add_option("--kind", args.kind, "compare or diagnose")->required()->type_name("compare|diagnose");
  an->add_option("--model", args.model, "a plant model's name on the server (GET /api/models)")->required()->type_name("NAME");
  an->add_flag("--wait", args.wait, "follow it to the end: the headline and the report's URL");
  CLI::App* list = command(ctl, "analyses", "a run's analyses with their state", [](const CtlArgs& a, const ApiClient& api) {
    const json j = checked(api.get("/api/runs/" + a.run + "/analyses"));
    if (a.json) {
      std::printf("%s\n", j.dump(2).c_str());
      return 0;
    }
    for (const auto& x : j["analyses"]) {
      std::printf("%-28s %-9s %-16s %-8s %s\n", x.value("id", "?").c_str(), x.value("kind", "?").c_str(),
                  x.value("model", "?").c_str(), x.value("state", "?").c_str(), analysis_headline(x).c_str());
    }
    return 0;
  });
  list->add_option("run", args.run, "the run's id (hilbench ctl runs)")->required()->type_name("RUN");
  list->add_flag("--json", args.json, "the server's answer as JSON");
}

}  // namespace

CommandRun define_ctl(CLI::App& ctl) {
  auto args = std::make_shared<CtlArgs>();
  auto handlers = std::make_shared<std::vector<std::pair<const CLI::App*, Handler>>>();
  ctl.add_option("--server", args->server_url, "the server")->type_name("URL")->envname("HILBENCH_SERVER")->capture_default_str();
  ctl.add_option("--token", args->token, "its token")->type_name("T")->envname("HILBENCH_TOKEN");
  ctl.require_subcommand(1);
  // The commands inherit fallthrough: --server and --token may come after the command too.
  ctl.fallthrough();
  define_commands(ctl, *args, *handlers);
  ctl.fallthrough(false);
  ctl.footer(
      "exit status: 0 success (a followed campaign completed), 1 error reply or failure,\n"
      "             2 usage, 3 a followed campaign ended stopped, aborted or in error,\n"
      "             or an analysis followed with --wait failed");
  return [args, handlers, &ctl] {
    const CLI::App* at = &ctl;
    while (!at->get_subcommands().empty()) at = at->get_subcommands().front();
    for (const auto& [cmd, handler] : *handlers) {
      if (cmd != at) continue;
      try {
        return handler(*args, ApiClient(args->server_url, args->token));
      } catch (const json::exception& e) {  // a field missing or of another type
        throw std::runtime_error(args->server_url + " answered with JSON that is not a hilbench server's reply (" +
                                 printable(e.what(), 200) + ")");
      }
    }
    throw UsageError("needs a command");  // unreachable: CLI11 requires one, and every leaf has a handler
  };
}

}  // namespace hil::bench
