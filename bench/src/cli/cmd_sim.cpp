// hilbench sim CAMPAIGN.yaml... [--out DIR] [--runs a,b] [--sensor-noise-kpa KPA] [--no-telemetry] [--quiet]
//              [--junit FILE] [--junit-relative]
#include <algorithm>
#include <cstdio>
#include <memory>

#include <spdlog/spdlog.h>

#include "commands.hpp"
#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/campaign/sim.hpp"
#include "hil/config.hpp"
#include "hil/line_file.hpp"
#include "hil/output_path.hpp"

namespace hil::bench {
std::vector<std::string> run_names(const std::string& list) {
  const std::vector<std::string> names = cfg::comma_list(list);
  if (names.empty())
    throw UsageError("--runs '" + list + "' names no run: name at least one, or leave --runs out to run them all");
  // An empty name between commas is a name lost (a script's empty variable), not a smaller choice.
  if (list.front() == ',' || list.back() == ',' || list.find(",,") != std::string::npos)
    throw UsageError("--runs '" + list + "' has an empty name between its commas");
  if (const std::string* twice = cfg::repeated(names)) throw UsageError("--runs names '" + *twice + "' twice");
  return names;
}

std::vector<std::string> chosen_runs(const Campaign& campaign, const std::string& list) {
  std::vector<std::string> unknown, all;
  for (const auto& r : campaign.runs) all.push_back(r.name);
  std::string runs;
  for (const auto& r : all) runs += (runs.empty() ? "" : ", ") + r;
  std::vector<std::string> names;
  try {
    names = run_names(list);
  } catch (const UsageError& e) {
    throw UsageError(std::string(e.what()) + "; the runs of campaign '" + campaign.name + "' are " + runs);
  }
  for (const auto& name : names)
    if (std::find(all.begin(), all.end(), name) == all.end()) unknown.push_back(name);
  if (!unknown.empty()) {
    std::string what;
    for (const auto& u : unknown) {
      const std::string hint = cfg::closest(u, all);
      what += (what.empty() ? "'" : ", '") + u + "'" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)");
    }
    throw UsageError("--runs: campaign '" + campaign.name + "' has no run " + what + "; its runs are " + runs);
  }
  return names;
}

namespace {

// The exit code of a sim whose runs all completed but a campaign's check failed: not 1 (an error
// in a file or a job), so a CI script can tell a regression from a broken setup.
constexpr int kChecksFailedExit = 3;

struct SimArgs {
  std::vector<std::string> campaign_files;
  std::string junit;  // empty: no JUnit XML
  std::string out_dir = "out";
  std::string runs;                       // comma-separated run names
  const CLI::Option* runs_opt = nullptr;  // not given: every run
  double sensor_noise_kpa = 0;
  const CLI::Option* sensor_noise = nullptr;  // given: the campaign's sensor noise is overridden
  bool no_telemetry = false;
  bool quiet = false;
  bool junit_relative = false;  // the report's path in the JUnit XML relative to the current folder
};

Campaign load_for_sim(const SimArgs& args, const std::string& file) {
  Campaign campaign = load_campaign(file);
  if (args.sensor_noise->count() > 0) {
    try {
      campaign = with_sensor_noise(std::move(campaign), args.sensor_noise_kpa);
    } catch (const std::invalid_argument& e) {  // beyond the sensor effect's range
      throw UsageError("--sensor-noise-kpa " + args.sensor_noise->as<std::string>() + ": " + e.what());
    }
  }
  return campaign;
}

// The verdict lines of a campaign's runs; returns how many checks failed.
long print_checks(const CampaignOutcome& out, bool quiet) {
  long failed = 0;
  for (const auto& r : out.runs) {
    for (const auto& c : r.checks) {
      if (c.verdict == Verdict::fail) ++failed;
      if (!quiet || c.verdict == Verdict::fail)
        std::printf("  %-7s %s/%s: %s\n", to_string(c.verdict), r.name.c_str(), c.check.c_str(), c.message.c_str());
    }
  }
  return failed;
}

// The campaigns to run and the files that could not be read. A broken file does not stop the
// others: CI gets their verdicts and the broken one as an error (file:line) in the JUnit XML,
// and the command still exits 1. What is wrong with the command line (two campaigns of one
// name, --runs) stops everything before anything runs.
struct Loaded {
  std::vector<Campaign> campaigns;
  std::vector<std::vector<std::string>> runs;  // each campaign's --runs; empty: every run
  std::vector<JunitSuite> broken;              // a suite of one error each
};

Loaded load_all(const SimArgs& args) {
  Loaded l;
  for (const auto& file : args.campaign_files) {
    try {
      l.campaigns.push_back(load_for_sim(args, file));
    } catch (const cfg::Error& e) {
      std::fprintf(stderr, "hilbench sim: %s\n", e.what());
      JunitSuite suite;
      suite.campaign = file;
      suite.error = e.what();
      l.broken.push_back(std::move(suite));
      continue;
    }
    const Campaign& c = l.campaigns.back();
    for (std::size_t i = 0; i + 1 < l.campaigns.size(); ++i) {
      if (l.campaigns[i].name == c.name)
        throw UsageError("campaigns " + l.campaigns[i].file.string() + " and " + file + " are both named '" + c.name +
                         "' (one output folder each): give one a different 'name:'");
    }
    l.runs.push_back(args.runs_opt->count() > 0 ? chosen_runs(c, args.runs) : std::vector<std::string>{});
  }
  return l;
}

// --junit must not replace a campaign or plant it reads, nor anything it did not write.
void check_junit(const SimArgs& args, const Loaded& l) {
  if (args.junit.empty()) return;
  std::vector<std::filesystem::path> inputs(args.campaign_files.begin(), args.campaign_files.end());
  for (const auto& c : l.campaigns) inputs.push_back(c.plant_file);
  check_output_file("--junit", args.junit, inputs, "the JUnit XML", kJunitSignature);
}

// The report as the JUnit XML names it: absolute, or relative to the current folder (the CI
// job's workspace, where Jenkins and GitLab look for an attachment).
std::string attachment(const SimArgs& args, const std::filesystem::path& report) {
  const auto absolute = std::filesystem::absolute(report);
  return args.junit_relative ? std::filesystem::relative(absolute).string() : absolute.string();
}

void print_outcome(const Campaign& campaign, const CampaignOutcome& out) {
  std::printf("%s: %zu run(s), %.1f s simulated in %.3f s (%.0fx real time)\n", campaign.name.c_str(), out.runs.size(),
              out.simulated_s, out.wall_s, out.simulated_s / out.wall_s);
  std::printf("  %-14s %10s %12s %12s %10s %8s\n", "run", "IAE MPa.s", "stall s", "gap est deg", "touch chg", "kicks");
  for (const auto& r : out.runs) {
    std::printf("  %-14s %10.4f %12.3f %12.3f %10ld %8ld\n", r.name.c_str(), r.summary.iae_mpa_s, r.summary.stall_s_total,
                r.summary.gap_est_final_deg, r.summary.touch_state_changes, r.summary.compensation_events);
  }
  std::printf("  report: %s\n", (out.dir / "report.html").c_str());
}

int run_sim(const SimArgs& args) {
  // Load and validate every campaign before anything is written.
  const Loaded loaded = load_all(args);
  check_junit(args, loaded);
  SimOptions options;
  options.out_dir = args.out_dir;
  options.telemetry = !args.no_telemetry;
  options.progress = !args.quiet;
  // SIGINT/SIGTERM: the runs stop at their next step and the half-made campaign folder goes.
  options.cancel = &StopSignal::install();
  std::vector<JunitSuite> suites = loaded.broken;
  long failed = 0;
  for (std::size_t i = 0; i < loaded.campaigns.size(); ++i) {
    const Campaign& campaign = loaded.campaigns[i];
    options.only_runs = loaded.runs[i];
    CampaignOutcome out;
    try {
      out = run_campaign(campaign, options);
    } catch (const Cancelled&) {
      spdlog::warn("sim {}: cancelled by {}; nothing was written to {}", campaign.name, StopSignal::name(),
                   options.out_dir.string());
      return StopSignal::exit_code();
    }
    if (!args.quiet) print_outcome(campaign, out);
    const long campaign_failed = print_checks(out, args.quiet);
    if (campaign_failed > 0) std::printf("%s: %ld check(s) failed\n", campaign.name.c_str(), campaign_failed);
    failed += campaign_failed;
    JunitSuite suite;
    suite.campaign = campaign.name;
    suite.report_path = attachment(args, out.dir / "report.html");
    suite.wall_s = out.wall_s;
    for (const auto& r : out.runs) suite.runs.push_back({r.name, r.wall_s, r.checks, "completed", ""});
    suites.push_back(std::move(suite));
  }
  if (!args.junit.empty()) {
    const std::filesystem::path junit(args.junit);
    if (junit.has_parent_path()) std::filesystem::create_directories(junit.parent_path());
    replace_file(junit, junit_xml(suites));
  }
  if (!loaded.broken.empty()) {
    std::fprintf(stderr, "hilbench sim: %zu campaign file(s) could not be read (above)%s\n", loaded.broken.size(),
                 args.junit.empty() ? "" : "; each is an error in the JUnit XML");
    return 1;
  }
  return failed > 0 ? kChecksFailedExit : 0;
}

}  // namespace

CommandRun define_sim(CLI::App& cmd) {
  auto args = std::make_shared<SimArgs>();
  cmd.add_option("campaign", args->campaign_files, "the campaign files, run one after the other")
      ->required()
      ->type_name("CAMPAIGN.yaml");
  cmd.add_option("--out", args->out_dir, "where OUT/<campaign>/ is written")
      ->type_name("DIR")
      ->check(path_value())
      ->capture_default_str();
  args->runs_opt = cmd.add_option("--runs", args->runs, "only these runs of the campaign")->type_name("a,b");
  args->sensor_noise =
      cmd.add_option("--sensor-noise-kpa", args->sensor_noise_kpa, "the transducer's noise RMS instead of the campaign's")
          ->type_name("KPA")
          ->check(non_negative_number());
  cmd.add_flag("--no-telemetry", args->no_telemetry, "no telemetry.csv per run (summaries and report only)");
  cmd.add_flag("--quiet", args->quiet, "no progress and no table of results (failed checks are still shown)");
  cmd.add_option("--junit", args->junit,
                 "write the campaigns' checks as JUnit XML (a testsuite per campaign, a testcase per run and check); "
                 "the exit code is 3 when a check fails")
      ->type_name("FILE")
      ->check(path_value());
  cmd.add_flag("--junit-relative", args->junit_relative,
               "the report's path in the JUnit XML relative to the current folder (the CI job's workspace), not absolute");
  return [args] { return run_sim(*args); };
}

}  // namespace hil::bench
