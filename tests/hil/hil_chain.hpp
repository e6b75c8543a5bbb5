// The whole HIL chain for tests: the simulator side in the test's own process (PlantService behind
// a CiA 402 drive emulator on a given CAN transport, a Modbus drive emulator and a Modbus
// transducer emulator on 127.0.0.1), rig files pointing at it, runs through CampaignRunner (what
// `hilbench serve` runs), and what a run left on disk compared with the pure simulation.
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/rt/plant_service.hpp"
#include "hil/bench/rt/rig_config.hpp"
#include "hil/bench/rt/rt_thread.hpp"
#include "hil/bench/server/runner.hpp"
#include "hil/bench/campaign/sim.hpp"
#include "hil/csv_reader.hpp"
#include "hil/drv/cia402_emulator.hpp"
#include "hil/drv/modbus_emulator.hpp"
#include "temp_file.hpp"

namespace hil::test {

using nlohmann::json;
using namespace std::chrono_literals;

inline constexpr std::uint32_t kFlagReadMissed = 1u << 4, kFlagSafeState = 1u << 6, kFlagDeviceFault = 1u << 8;

inline const bench::Campaign& paper_adaptive_campaign() {
  static const bench::Campaign c = bench::load_campaign(source_path("configs/campaigns/paper_adaptive.yaml"));
  return c;
}

// paper_adaptive's plant, controller and reference, shortened (the reference still alternates
// 1.0 / 1.5 MPa every 2.5 s from 2.5 s). gap_step_s > 0: the gap grows 1 -> 2 deg then.
// period_ms: the control period dT.
inline bench::Campaign short_paper_campaign(double duration_s, double gap_step_s = 0, double period_ms = 1) {
  std::string yaml =
      "name: short_paper\n"
      "plant: ../plant/nominal.yaml\n"
      "duration_s: " +
      std::to_string(duration_s) +
      "\n"
      "period_ms: " +
      std::to_string(period_ms) +
      "\n"
      "seed: 1\n"
      "sensor_noise_kpa: 2.0\n"
      "reference:\n"
      "  initial_mpa: 1.0\n" +
      (duration_s > 2.5 ? "  profile:\n"
                          "    - square: {from_s: 2.5, half_period_s: 2.5, low_mpa: 1.0, high_mpa: 1.5}\n"
                        : "") +
      "gap:\n"
      "  initial_deg: 1.0\n";
  if (gap_step_s > 0) yaml += "  changes:\n    - step: {at_s: " + std::to_string(gap_step_s) + ", to_deg: 2.0}\n";
  yaml +=
      "runs:\n"
      "  - name: adaptive\n"
      "    compensation: adaptive\n"
      "    initial_gap_deg: 0\n";
  return bench::load_campaign_text(yaml, "short_paper (test)", source_path("configs/campaigns"));
}

inline constexpr std::uint8_t kNode = 5;
inline const drv::DriveUnits kUnits{131072, 1.0, 1};  // as drivers/configs/cia402_*.yaml

// The simulator side: the campaign's plant in real time behind the three emulators.
struct SimulatorSide {
  SimulatorSide(const bench::Campaign& c, const drv::CanTransportFactory& can_transport,
                const std::string& can_interface = "vcan0")
      : plant(config(c)),
        can(drv::Cia402EmulatorConfig{can_interface, kNode, kUnits}, plant.add_drive(), can_transport),
        drive(tcp(0), drv::RegisterMap::load(source_path("drivers/configs/modbus_drive_map.yaml")), plant.add_drive()),
        transducer(tcp(0), drv::RegisterMap::load(source_path("drivers/configs/modbus_transducer_map.yaml")),
                   plant.transducer()) {
    plant.start();
    io_sched.reset();
  }
  static bench::PlantServiceConfig config(const bench::Campaign& c) {
    bench::PlantServiceConfig p;
    p.plant = c.plant;
    p.period_s = c.period_s;
    p.p_initial_pa = c.reference_pa.at(0.0);
    p.seed = c.seed;
    p.gap_program = c.gap_rad;
    p.rt_priority = kPriority;
    return p;
  }
  static constexpr int kPriority = 75;
  static drv::ModbusLinkConfig tcp(int port) {
    drv::ModbusLinkConfig l;
    l.host = "127.0.0.1";
    l.port = port;
    return l;
  }
  // SCHED_FIFO while the emulators start their threads, so they answer at once as a device would
  // (the rig's own I/O threads run at 70, the loop at 80); back to normal once they run.
  std::optional<bench::ScopedRealtime> io_sched;
  bool io_raised = (io_sched.emplace(kPriority), true);
  bench::PlantService plant;
  drv::Cia402DriveEmulator can;
  drv::ModbusDriveEmulator drive;
  drv::ModbusTransducerEmulator transducer;
};

// Device entries of a rig file (inline client configurations). The heartbeat timeout is 1 s
// unless a test is about it: a machine busy with other work can starve an emulator's thread (or
// the VM's vCPU) for 100 ms, and a run that is not about heartbeats must not trip on that.
inline constexpr int kBusyHeartbeatTimeoutMs = 1000;
inline std::string can_drive_yaml(const std::string& interface = "vcan0", const std::string& bus_off_policy = "recover",
                                  int heartbeat_timeout_ms = kBusyHeartbeatTimeoutMs, const std::string& limits = "",
                                  const std::string& bench_heartbeat = "") {
  return "    cia402: {interface: " + interface + ", node_id: 5, units: {counts_per_rev: 131072},\n" +
         (limits.empty() ? std::string() : "             limits: " + limits + ",\n") +
         (bench_heartbeat.empty() ? std::string() : "             bench_heartbeat: " + bench_heartbeat + ",\n") +
         "             heartbeat: {producer_ms: 20, timeout_ms: " + std::to_string(heartbeat_timeout_ms) +
         "},\n"
         "             timeouts: {boot_ms: 10000, sdo_ms: 500, sdo_retries: 2, transition_ms: 3000},\n"
         "             bus_off: {policy: " +
         bus_off_policy + ", recover_after_ms: 200}}\n";
}
inline std::string modbus_device_yaml(int port, const std::string& map, double max_age_ms = 4, int response_timeout_ms = 100) {
  return "    modbus: {link: {transport: tcp, host: 127.0.0.1, port: " + std::to_string(port) +
         ", poll_period_ms: 2, response_timeout_ms: " + std::to_string(response_timeout_ms) +
         ", reconnect: {initial_ms: 20, max_ms: 200}},\n"
         "             register_map: " +
         source_path("drivers/configs/" + map).string() +
         "}\n"
         "    max_age_ms: " +
         std::to_string(max_age_ms) + "\n";
}

// The watchdog: 500 periods by default here, so that it ends a run whose chain broke, not one the
// machine slowed down. This machine preempts a vCPU for ~4.5 ms now and then, and with other
// builds running the loop wakes up to 90 ms late in the VM: a few periods' watchdog would trip on
// that alone. The fault tests set the watchdog where it is their subject (rig_fault_scenarios.hpp).
struct RigOptions {
  std::string loop_extra;    // more keys of the loop block, e.g. "target_shaping: {...}"
  std::string safety_extra;  // more keys of the safety block, e.g. "following_error: {...}"
  int watchdog_misses = 500;
  int safe_hold_ms = 200;
  int priority = 80;  // SCHED_FIFO as the shipped rigs (a warning where refused)
  int cpu = 1;
  int io_priority = 70;
};

// A rig file: kind can (CAN drive + transducer), modbus (both Modbus) or hybrid (the drive given).
inline std::string rig_yaml(const std::string& kind, const std::string& drive, const std::string& transducer, RigOptions o = {}) {
  std::string y = "kind: " + kind + "\ndescription: test rig\ndevices:\n  drive:\n" + drive;
  if (!transducer.empty()) y += "  transducer:\n" + transducer;
  y += "loop: {priority: " + std::to_string(o.priority) + ", cpu: " + std::to_string(o.cpu) +
       ", io_priority: " + std::to_string(o.io_priority) + (o.loop_extra.empty() ? "" : ", " + o.loop_extra) +
       "}\n"
       "safety: {cmd_min_deg: -5, cmd_max_deg: 35, rate_limit_deg_s: 10000, p_max_mpa: 2.5, p_min_mpa: 0.2,\n"
       "         watchdog_misses: " +
       std::to_string(o.watchdog_misses) + ", safe_state: hold, safe_hold_ms: " + std::to_string(o.safe_hold_ms) +
       (o.safety_extra.empty() ? "" : ", " + o.safety_extra) + "}\n";
  return y;
}
// Client timeouts of a rig file: the defaults of the device entries above (a heartbeat of 1 s, a
// Modbus reply within 100 ms), or `relaxed` where only completion matters on a busy machine.
struct ClientTimeouts {
  int heartbeat_ms = kBusyHeartbeatTimeoutMs;
  int modbus_response_ms = 100;
};
inline constexpr ClientTimeouts kRelaxedTimeouts{kBusyHeartbeatTimeoutMs, 1000};
inline std::string can_rig_yaml(const SimulatorSide& s, RigOptions o = {}, const std::string& interface = "vcan0",
                                const std::string& bus_off_policy = "recover", ClientTimeouts t = {}) {
  return rig_yaml("can", can_drive_yaml(interface, bus_off_policy, t.heartbeat_ms),
                  modbus_device_yaml(s.transducer.port(), "modbus_transducer_map.yaml", 4, t.modbus_response_ms), o);
}
inline std::string modbus_rig_yaml(const SimulatorSide& s, RigOptions o = {}, ClientTimeouts t = {}) {
  return rig_yaml("modbus", modbus_device_yaml(s.drive.port(), "modbus_drive_map.yaml", 4, t.modbus_response_ms),
                  modbus_device_yaml(s.transducer.port(), "modbus_transducer_map.yaml", 4, t.modbus_response_ms), o);
}

// A campaign run through CampaignRunner, as `hilbench serve` runs it, into its own runs folder.
class Bench {
 public:
  explicit Bench(drv::CanTransportFactory can_transport = {}) {
    bench::RunnerOptions o;
    o.runs_dir = dir_.path() / "runs";
    o.version = "test";
    o.can_transport = std::move(can_transport);
    runner_ = std::make_unique<bench::CampaignRunner>(o);
  }
  void start(const bench::Campaign& c, const std::string& rig_text, const std::vector<std::string>& runs = {"adaptive"}) {
    bench::StartRequest r;
    r.campaign = c;
    r.rig = bench::load_rig_config(dir_.write("rigs/test_rig_" + std::to_string(++rigs_) + ".yaml", rig_text));
    r.runs = runs;
    r.source = "test";
    runner_->start(std::move(r));
  }
  // Waits until the running campaign's loop time reaches t_s (false: it ended or timed out first).
  bool wait_t(double t_s, std::chrono::seconds timeout = 30s) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < end) {
      const json s = runner_->status();
      if (s["state"] == "idle") return false;
      if (s.contains("progress") && s["progress"]["t_s"].get<double>() >= t_s) return true;
      std::this_thread::sleep_for(5ms);
    }
    return false;
  }
  json finish(std::chrono::seconds timeout = 60s) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (runner_->running() && std::chrono::steady_clock::now() < end) std::this_thread::sleep_for(10ms);
    EXPECT_FALSE(runner_->running()) << "the campaign did not end";
    runner_->wait();
    return runner_->status()["last"];
  }
  bench::CampaignRunner& runner() { return *runner_; }
  // The run folders, oldest first.
  std::vector<std::filesystem::path> runs() const {
    std::vector<std::filesystem::path> d;
    for (const auto& e : std::filesystem::directory_iterator(dir_.path() / "runs")) d.push_back(e.path());
    std::sort(d.begin(), d.end());
    return d;
  }
  const TempDir& dir() const { return dir_; }

 private:
  TempDir dir_;
  int rigs_ = 0;
  std::unique_ptr<bench::CampaignRunner> runner_;
};

// What a run left on disk, every telemetry row parsed strictly.
struct RunFiles {
  explicit RunFiles(const std::filesystem::path& d, bool truth = false) : dir(d) {
    if (getenv("HIL_KEEP_RUN"))
      std::filesystem::copy(d, std::filesystem::path(getenv("HIL_KEEP_RUN")) / d.filename(),
                            std::filesystem::copy_options::recursive | std::filesystem::copy_options::overwrite_existing);
    std::ifstream in(d / "run.json");
    run = json::parse(in);
    std::ifstream ev(d / "events.jsonl");
    for (std::string line; std::getline(ev, line);) events.push_back(json::parse(line));
    std::vector<std::string> cols = {"t_s", "p_meas_mpa", "theta_cmd_deg", "theta_motor_deg", "p_ref_mpa", "loop_flags"};
    if (truth) cols.insert(cols.end(), {"theta_valve_deg", "gap_true_deg", "p_chamber_mpa"});
    csv = read_csv(d / "telemetry.csv", {cols, {}, "t_s"}, &header);
  }
  const json* event(const std::string& kind) const {
    for (const auto& e : events) {
      if (e.value("kind", "") == kind) return &e;
    }
    return nullptr;
  }
  std::uint32_t flags(std::size_t row) const { return static_cast<std::uint32_t>(csv.values[5][row]); }
  bool has_column(const std::string& name) const {
    return std::find(header.names.begin(), header.names.end(), name) != header.names.end();
  }
  // The first row in the safe state, and the first row of the streak of missed readings that led
  // to it (the period the loop first saw the fault). -1 when there is none.
  std::pair<long, long> fault_and_safe_rows() const {
    long safe = -1;
    for (std::size_t i = 0; i < csv.rows(); ++i) {
      if (flags(i) & kFlagSafeState) {
        safe = static_cast<long>(i);
        break;
      }
    }
    if (safe < 0) return {-1, -1};
    long first = safe;
    while (first > 0 && (flags(static_cast<std::size_t>(first - 1)) & kFlagReadMissed)) --first;
    if (!(flags(static_cast<std::size_t>(first)) & kFlagReadMissed)) first = -1;
    return {first, safe};
  }
  std::filesystem::path dir;
  json run;
  std::vector<json> events;
  CsvHeader header;
  CsvChunk csv;
};

// RMS of the run's measured pressure minus the pure simulation's (`hilbench sim`, same campaign
// and run), period by period, in % of the reference's range.
struct TraceDiff {
  double rms_mpa = 0, range_mpa = 0, percent = 0, max_abs_mpa = 0;
  std::size_t rows = 0;
};
inline TraceDiff compare_with_simulation(const bench::Campaign& c, const std::string& run, const CsvChunk& csv) {
  const bench::RunSpec* spec = nullptr;
  for (const auto& r : c.runs) {
    if (r.name == run) spec = &r;
  }
  EXPECT_NE(spec, nullptr);
  std::vector<bench::StepRecord> sim;
  bench::simulate_run(c, *spec, [&](const bench::TelemetryRecord& r) { sim.push_back(r.step); });
  TraceDiff d;
  double lo = 1e300, hi = -1e300, sum = 0;
  d.rows = std::min(csv.rows(), sim.size());
  for (std::size_t i = 0; i < d.rows; ++i) {
    EXPECT_NEAR(csv.values[0][i], sim[i].t_s, 1e-9);
    const double e = csv.values[1][i] - sim[i].p_meas_pa * 1e-6;
    sum += e * e;
    d.max_abs_mpa = std::max(d.max_abs_mpa, std::abs(e));
    lo = std::min(lo, sim[i].p_ref_pa * 1e-6);
    hi = std::max(hi, sim[i].p_ref_pa * 1e-6);
  }
  d.rms_mpa = std::sqrt(sum / static_cast<double>(std::max<std::size_t>(d.rows, 1)));
  d.range_mpa = hi - lo;
  d.percent = 100 * d.rms_mpa / d.range_mpa;
  return d;
}

}  // namespace hil::test
