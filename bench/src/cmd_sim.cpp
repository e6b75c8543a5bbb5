// hilbench sim CAMPAIGN.yaml [--out DIR] [--runs a,b] [--no-telemetry] [--quiet]
#include <csignal>
#include <cstdio>
#include <sstream>

#include "cli.hpp"
#include "commands.hpp"
#include "hil/bench/campaign.hpp"
#include "hil/bench/sim.hpp"

namespace hil::bench {
namespace {
std::atomic<bool> g_cancel{false};
volatile std::sig_atomic_t g_signal = 0;
extern "C" void on_cancel_signal(int sig) {
  g_signal = sig;
  g_cancel.store(true);
}
}  // namespace

int cmd_sim(const std::vector<std::string>& argv) {
  const Args args = parse_args(argv, {"out", "runs", "sensor-noise-kpa"}, {"no-telemetry", "quiet"});
  if (args.positional.size() != 1) throw UsageError("sim needs exactly one campaign file");
  // Load and validate everything before anything is written.
  Campaign campaign = load_campaign(args.positional[0]);
  if (args.options.count("sensor-noise-kpa")) {
    const double kpa = args.number("sensor-noise-kpa", 0);
    if (!(kpa >= 0)) throw UsageError("--sensor-noise-kpa cannot be negative, got " + args.option("sensor-noise-kpa", ""));
    try {
      campaign = with_sensor_noise(std::move(campaign), kpa);
    } catch (const std::invalid_argument& e) {  // beyond the sensor effect's range
      throw UsageError("--sensor-noise-kpa " + args.option("sensor-noise-kpa", "") + ": " + e.what());
    }
  }
  SimOptions options;
  options.out_dir = args.option("out", "out");
  options.telemetry = !args.has("no-telemetry");
  options.progress = !args.has("quiet");
  options.cancel = &g_cancel;
  // SIGINT/SIGTERM: the runs stop at their next step and the half-made campaign folder goes.
  std::signal(SIGINT, on_cancel_signal);
  std::signal(SIGTERM, on_cancel_signal);
  std::stringstream runs(args.option("runs", ""));
  for (std::string name; std::getline(runs, name, ',');) {
    if (!name.empty()) options.only_runs.push_back(name);
  }
  CampaignOutcome out;
  try {
    out = run_campaign(campaign, options);
  } catch (const Cancelled&) {
    std::fprintf(stderr, "sim %s: cancelled by %s; nothing was written to %s\n", campaign.name.c_str(),
                 g_signal == SIGTERM ? "SIGTERM" : "SIGINT", options.out_dir.c_str());
    return 128 + static_cast<int>(g_signal);
  }
  if (!args.has("quiet")) {
    std::printf("%s: %zu run(s), %.1f s simulated in %.3f s (%.0fx real time)\n", campaign.name.c_str(), out.runs.size(),
                out.simulated_s, out.wall_s, out.simulated_s / out.wall_s);
    std::printf("  %-14s %10s %12s %12s %10s %8s\n", "run", "IAE MPa.s", "stall s", "gap est deg", "touch chg", "kicks");
    for (const auto& r : out.runs) {
      std::printf("  %-14s %10.4f %12.3f %12.3f %10ld %8ld\n", r.name.c_str(), r.summary.iae_mpa_s,
                  r.summary.stall_s_total, r.summary.gap_est_final_deg, r.summary.touch_state_changes,
                  r.summary.compensation_events);
    }
    std::printf("  report: %s\n", (out.dir / "report.html").c_str());
  }
  return 0;
}

}  // namespace hil::bench
