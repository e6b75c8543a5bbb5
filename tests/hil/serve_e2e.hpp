// End to end through real processes: `hilbench plant` (the simulator side: the campaign's plant
// behind the CiA 402 emulator on a CAN interface and/or the Modbus emulators on 127.0.0.1) and
// `hilbench serve` (the bench, driven over its HTTP API), with a rig file pointing one at the
// other. The run's pressure trace is compared with the pure simulation of the same campaign.
// Used on the host (Modbus rig, serve_e2e_test.cpp) and in the vcan VM (CAN rig, vcan_rigs_test.cpp).
#pragma once

#include <signal.h>

#include <fstream>
#include <functional>
#include <sstream>

#include "bench/server_process.hpp"
#include "hil_chain.hpp"

namespace hil::test {

// `hilbench plant` on a campaign, with its emulators at SCHED_FIFO 75 (as in-process tests run them).
class PlantProcess {
 public:
  PlantProcess(const std::filesystem::path& campaign, std::vector<std::string> devices, const std::filesystem::path& dir) {
    log_ = dir / "plant.log";
    port_file_ = dir / "plant_ports.json";
    std::vector<std::string> argv = {hilbench_exe(),
                                     "plant",
                                     "--campaign",
                                     campaign.string(),
                                     "--port-file",
                                     port_file_.string(),
                                     "--rt-priority",
                                     "75",
                                     "--quiet",
                                     "--can-config",
                                     source_path("drivers/configs/cia402_emulator.yaml").string(),
                                     "--drive-map",
                                     source_path("drivers/configs/modbus_drive_map.yaml").string(),
                                     "--transducer-map",
                                     source_path("drivers/configs/modbus_transducer_map.yaml").string()};
    argv.insert(argv.end(), devices.begin(), devices.end());
    pid_ = spawn(argv, log_);
    for (int i = 0; i < 6000 && !std::filesystem::exists(port_file_); ++i) {  // 60 s: the VM is slow to start
      if (const auto rc = wait_exit(pid_, std::chrono::milliseconds(10))) {
        pid_ = 0;
        throw std::runtime_error("hilbench plant exited with " + std::to_string(*rc) + ":\n" + slurp(log_));
      }
    }
    if (!std::filesystem::exists(port_file_)) throw std::runtime_error("hilbench plant did not get ready:\n" + slurp(log_));
    ports_ = nlohmann::json::parse(slurp(port_file_));
  }
  ~PlantProcess() {
    if (pid_ > 0) {
      kill(pid_, SIGTERM);
      if (!wait_exit(pid_, std::chrono::seconds(10))) {
        kill(pid_, SIGKILL);
        wait_exit(pid_, std::chrono::seconds(5));
      }
    }
    if (::testing::Test::HasFailure()) std::fprintf(stderr, "---- plant log ----\n%s-------------------\n", slurp(log_).c_str());
  }
  PlantProcess(const PlantProcess&) = delete;
  PlantProcess& operator=(const PlantProcess&) = delete;
  int drive_port() const { return ports_["modbus_drive_port"]; }
  int transducer_port() const { return ports_["transducer_port"]; }

 private:
  std::filesystem::path log_, port_file_;
  nlohmann::json ports_;
  pid_t pid_ = 0;
};

struct ServeResult {
  TraceDiff diff;
  long stale_periods = 0;
  nlohmann::json run;
  std::string outcome, reason;  // run.json's
};

// configs/campaigns/paper_adaptive.yaml's text with `period_ms` as its dT (the VM runs it slower).
inline std::string paper_adaptive_yaml(double period_ms) {
  std::string yaml = slurp(source_path("configs/campaigns/paper_adaptive.yaml"));
  const auto at = yaml.find("period_ms: 1 ");
  if (at == std::string::npos) throw std::runtime_error("paper_adaptive.yaml: no 'period_ms: 1 '");
  std::ostringstream period;
  period << "period_ms: " << period_ms << " ";
  yaml.replace(at, 13, period.str());
  return yaml;
}

// paper_adaptive (with `period_ms` as its dT) run by `hilbench serve` on the rig `rig_text(plant)`
// returns, against `hilbench plant` with `devices` (e.g. --modbus tcp:127.0.0.1:0).
// `may_abort`: a run that aborted is returned as it is (outcome, reason, run.json) for the caller
// to judge; otherwise only a completed run passes.
inline ServeResult serve_paper_adaptive(double period_ms, const std::vector<std::string>& devices,
                                        const std::function<std::string(const PlantProcess&)>& rig_text, bool may_abort = false) {
  TempDir configs;
  std::filesystem::create_symlink(source_path("configs/plant"), configs.path() / "plant");
  const auto campaign_file = configs.write("campaigns/paper_adaptive.yaml", paper_adaptive_yaml(period_ms));
  const bench::Campaign campaign = bench::load_campaign(campaign_file);

  PlantProcess plant(campaign_file, devices, configs.path());
  configs.write("rigs/e2e.yaml", rig_text(plant));
  ServerProcess server({"--configs", configs.path().string()});
  const auto api = server.client();
  const auto started = api.post("/api/start", {{"campaign", "paper_adaptive"}, {"rig", "e2e"}, {"runs", {"adaptive"}}});
  EXPECT_EQ(started.status, 202) << started.body;
  // Polled slowly: in the VM every status request costs the loop's CPUs milliseconds.
  nlohmann::json s;
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(static_cast<long>(campaign.duration_s * 3 + 60));
  do {
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    s = api.get("/api/status").json();
  } while (s["state"] != "idle" && std::chrono::steady_clock::now() < until);
  EXPECT_EQ(s["state"], "idle") << s.dump(2);
  const RunFiles f(only_run(server.runs_dir()));
  ServeResult r;
  r.run = f.run;
  r.outcome = f.run.value("outcome", "");
  r.reason = f.run["reason"].is_string() ? f.run["reason"].get<std::string>() : "";
  if (may_abort && r.outcome == "aborted") return r;
  EXPECT_EQ(s["last"]["outcome"], "completed") << s.dump(2);
  EXPECT_EQ(f.csv.rows(), static_cast<std::size_t>(std::lround(campaign.duration_s / campaign.period_s)));
  EXPECT_EQ(f.run["telemetry"]["rows_lost"], 0);
  for (std::size_t i = 0; i < f.csv.rows(); ++i) r.stale_periods += (f.flags(i) & kFlagReadMissed) != 0;
  r.diff = compare_with_simulation(campaign, "adaptive", f.csv);
  const auto& loop = f.run["loop"];
  std::printf(
      "%s rig through hilbench serve, dT %.3g ms: pressure RMS difference to the simulation %.2f kPa = %.2f %% of the "
      "%.2f MPa range (max %.1f kPa); stale periods %ld of %zu; wake-up p50/p99/max %.1f/%.1f/%.0f us, "
      "compute p99 %.1f us, overruns %lld, skipped deadlines %lld\n",
      f.run["rig"]["kind"].get<std::string>().c_str(), period_ms, r.diff.rms_mpa * 1e3, r.diff.percent, r.diff.range_mpa,
      r.diff.max_abs_mpa * 1e3, r.stale_periods, f.csv.rows(), loop["wake_latency_us"]["p50_us"].get<double>(),
      loop["wake_latency_us"]["p99_us"].get<double>(), loop["wake_latency_us"]["max_us"].get<double>(),
      loop["compute_us"]["p99_us"].get<double>(), loop["overruns"].get<long long>(), loop["skipped_deadlines"].get<long long>());
  return r;
}

}  // namespace hil::test
