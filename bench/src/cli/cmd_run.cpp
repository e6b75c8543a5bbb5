// hilbench run CAMPAIGN.yaml --rig NAME [--out DIR] [--configs DIR] [--runs a,b] [--speed X] [--junit FILE]
//              [--no-mlock] [--quiet]
//
// A bench run from the command line, without the server: the campaign's runs one after the
// other on the rig, through the same campaign runner `hilbench serve` starts them with, so each
// run leaves the same record (OUT/<UTC start>_<campaign>_<run>/ with run.json, telemetry.csv,
// telemetry.mcap, events.jsonl; the checks' verdicts in run.json) and keeps the same interlocks.
// Ctrl-C or SIGTERM aborts the run under way (the loop takes the rig to its safe state) and ends
// the command once the record is written; a second Ctrl-C does not cut that short (SIGQUIT,
// Ctrl-\, kills at once and leaves the run to be marked interrupted). A rig that needs an
// operator link is refused: only the server has one. Runs an earlier process left "running"
// (kill -9) in OUT are marked interrupted first.
// Exit codes: 0 every run completed and no check failed, 3 a check failed (as `hilbench sim`),
// 1 a run did not complete (error, abort, trip), 128 + the signal on Ctrl-C or SIGTERM.
#include <chrono>
#include <cstdio>
#include <memory>
#include <thread>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "ctl_junit.hpp"
#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/rt/rig_config.hpp"
#include "hil/bench/rt/rt_thread.hpp"
#include "hil/bench/server/runner.hpp"
#include "hil/config.hpp"

namespace hil::bench {
namespace {

// As `hilbench sim`: a regression (a failed check) is told apart from a broken setup (1).
constexpr int kChecksFailedExit = 3;

struct RunArgs {
  std::string campaign_file;
  std::string rig;  // a name in CONFIGS/rigs/, or a rig file's path
  std::string configs_dir = "configs";
  std::string out_dir = "runs";
  std::string runs;                       // comma-separated run names
  const CLI::Option* runs_opt = nullptr;  // not given: every run
  std::string junit;                      // empty: no JUnit XML
  double speed = 1.0;
  bool no_mlock = false;
  bool quiet = false;
};

// --rig NAME is CONFIGS/rigs/NAME.yaml, as the API's `rig` field; a path (a '/' or a .yaml) is the file itself.
std::filesystem::path rig_file(const RunArgs& args) {
  const std::filesystem::path given(args.rig);
  if (args.rig.find('/') != std::string::npos || given.extension() == ".yaml") return given;
  const std::filesystem::path file = std::filesystem::path(args.configs_dir) / "rigs" / (args.rig + ".yaml");
  if (!std::filesystem::is_regular_file(file)) {
    std::vector<std::string> names;
    std::error_code ec;
    for (const auto& e : std::filesystem::directory_iterator(std::filesystem::path(args.configs_dir) / "rigs", ec))
      if (e.path().extension() == ".yaml") names.push_back(e.path().stem().string());
    const std::string hint = cfg::closest(args.rig, names);
    throw UsageError("--rig " + args.rig + ": no rig file " + file.string() +
                     (hint.empty() ? "" : " (did you mean '" + hint + "'?)") + " (give --configs DIR or the file's path)");
  }
  return file;
}

// The verdict lines of a finished run (its checks_json); returns how many failed.
long print_checks(const std::string& run, const nlohmann::json& checks, bool quiet) {
  long failed = 0;
  if (!checks.is_object()) return 0;
  for (const auto& c : checks.value("results", nlohmann::json::array())) {
    const std::string verdict = c.value("verdict", "");
    if (verdict == "fail") ++failed;
    if (!quiet || verdict == "fail")
      std::printf("  %-7s %s/%s: %s\n", verdict.c_str(), run.c_str(), c.value("check", "").c_str(),
                  c.value("message", "").c_str());
  }
  return failed;
}

// A rig whose safety needs an operator polling (require_operator) trips when nobody is heard;
// without a server nobody can be: refused before anything is opened.
void refuse_operator_rig(const RigConfig& rig) {
  if (!rig.require_operator) return;
  throw std::runtime_error(rig.file.string() +
                           ": require_operator: true needs an operator link (the console or `hilbench ctl` "
                           "polling the server), which only `hilbench serve` has; run this rig through the server, or with a "
                           "rig file without require_operator");
}

// Until the campaign ends; the first SIGINT or SIGTERM aborts it (the safe state, then the
// record). True when a signal did.
bool wait_aborting_on_signal(CampaignRunner& runner, const std::atomic<bool>& signalled) {
  bool aborted = false;
  while (runner.running()) {
    if (signalled.load() && !aborted) {
      aborted = true;
      try {
        runner.abort(std::string(StopSignal::name()) + " (hilbench run)");
      } catch (const Conflict&) {  // the campaign ended meanwhile
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  runner.wait();
  return aborted;
}

struct RunsTally {
  long failed = 0;
  bool incomplete = false;
};

// Each run's outcome and checks, as the runner's last campaign has them.
RunsTally print_runs(const std::string& campaign, const nlohmann::json& last, const RunArgs& args) {
  RunsTally t;
  for (const auto& r : last.value("runs", nlohmann::json::array())) {
    const std::string name = r.value("run", ""), outcome = r.value("outcome", "");
    const bool completed = outcome == "completed";
    t.incomplete = t.incomplete || !completed;
    if (!args.quiet || !completed) {
      std::printf("%s/%s: %s%s  %s\n", campaign.c_str(), name.c_str(), outcome.c_str(),
                  r["reason"].is_string() ? (" (" + r["reason"].get<std::string>() + ")").c_str() : "",
                  (std::filesystem::path(args.out_dir) / r.value("dir", "")).c_str());
    }
    t.failed += print_checks(name, r.value("checks", nlohmann::json()), args.quiet);
  }
  if (last.contains("runs_skipped")) std::printf("%s: %d run(s) not run\n", campaign.c_str(), last["runs_skipped"].get<int>());
  if (t.failed > 0) std::printf("%s: %ld check(s) failed\n", campaign.c_str(), t.failed);
  return t;
}

int run_run(const RunArgs& args) {
  // Everything is read and checked before a folder is made or a device opened.
  const Campaign campaign = load_campaign(args.campaign_file);
  const std::filesystem::path rig_path = rig_file(args);
  const RigConfig rig = load_rig_config(rig_path);
  refuse_operator_rig(rig);
  const std::vector<std::string> runs =
      args.runs_opt->count() > 0 ? chosen_runs(campaign, args.runs) : std::vector<std::string>{};
  if (!args.junit.empty()) check_junit_output(args.junit, {args.campaign_file, rig_path, campaign.plant_file});
  // A run a killed `hilbench run` (or server) left "running" gets its honest end first.
  for (const auto& dir : mark_interrupted_runs(args.out_dir, "hilbench run"))
    std::fprintf(stderr, "run %s: its process ended during the run; marked interrupted\n", dir.filename().c_str());
  std::string mlock_warning = "not requested (--no-mlock)";
  if (!args.no_mlock) {
    mlock_warning = lock_memory();
    if (!mlock_warning.empty()) std::fprintf(stderr, "warning: %s\n", mlock_warning.c_str());
  }
  RunnerOptions options;
  options.runs_dir = args.out_dir;
  options.version = HIL_VERSION;
  options.mlock_warning = mlock_warning;
  options.recorded_by = "hilbench run";
  const bool quiet = args.quiet;
  options.on_notice = [quiet](const nlohmann::json& j) {  // the runner's thread
    if (quiet || j.value("type", "") != "run_start") return;
    std::printf("%s/%s: running (%s)\n", j.value("campaign", "").c_str(), j.value("run", "").c_str(), j.value("dir", "").c_str());
    std::fflush(stdout);
  };
  CampaignRunner runner(std::move(options));
  StartRequest request;
  request.campaign = campaign;
  request.rig = rig;
  request.runs = runs;
  request.speed = args.speed;
  request.source = args.campaign_file;
  const std::atomic<bool>& signalled = StopSignal::install(StopSignal::Repeat::waits_for_safe_state);
  try {
    runner.start(std::move(request));
  } catch (const BadField& e) {  // a run name or a speed this rig cannot take
    throw UsageError("--" + e.field + ": " + e.what());
  }
  const bool aborted = wait_aborting_on_signal(runner, signalled);
  const nlohmann::json last = runner.status()["last"];
  const RunsTally tally = print_runs(campaign.name, last, args);
  if (!args.junit.empty()) write_served_junit(last, args.junit);
  if (aborted) return StopSignal::exit_code();
  if (tally.incomplete || last.contains("runs_skipped")) return 1;
  return tally.failed > 0 ? kChecksFailedExit : 0;
}

}  // namespace

CommandRun define_run(CLI::App& cmd) {
  auto args = std::make_shared<RunArgs>();
  cmd.add_option("campaign", args->campaign_file, "the campaign file")->required()->type_name("CAMPAIGN.yaml");
  cmd.add_option("--rig", args->rig, "the rig: a name in CONFIGS/rigs/ (sim, hybrid, can, modbus) or a rig file")
      ->required()
      ->type_name("NAME")
      ->check(path_value());
  cmd.add_option("--out", args->out_dir, "where each run's folder is made (as hilbench serve's --runs-dir)")
      ->type_name("DIR")
      ->check(path_value())
      ->capture_default_str();
  cmd.add_option("--configs", args->configs_dir, "the folder holding rigs/")
      ->type_name("DIR")
      ->check(path_value())
      ->capture_default_str();
  args->runs_opt = cmd.add_option("--runs", args->runs, "only these runs of the campaign")->type_name("a,b");
  cmd.add_option("--speed", args->speed, "loop periods per control period of wall time (simulated rigs only)")
      ->type_name("X")
      ->check(number_in(kMinSpeed, kMaxSpeed))
      ->capture_default_str();
  cmd.add_option("--junit", args->junit,
                 "write the runs' checks as JUnit XML (a testcase per run and check; a run that did not complete is an "
                 "error)")
      ->type_name("FILE")
      ->check(path_value());
  cmd.add_flag("--no-mlock", args->no_mlock, "do not lock the process's memory");
  cmd.add_flag("--quiet", args->quiet, "only what did not complete and failed checks");
  return [args] { return run_run(*args); };
}

}  // namespace hil::bench
