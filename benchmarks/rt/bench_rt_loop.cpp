// The real-time loop on the simulated rig, through the campaign runner exactly as `hilbench serve`
// runs it (loop thread, recorder thread, files), for a fixed time at a chosen rate. Prints the
// wake-up latency and compute time percentiles, overruns and telemetry loss from run.json.
//   bench_rt_loop [--hz 1000] [--seconds 60] [--priority 80] [--cpu 1] [--rig configs/rigs/sim.yaml] [--keep DIR]
//                 [--can loopback|IFACE] [--compensator NAME]
// Compare with cyclictest run the same way: benchmarks/rt/compare.sh.
// --can: the CAN rig instead, against the simulator side in this process (the plant stepping
// every 1 ms behind a CiA 402 drive emulator and a Modbus transducer emulator on 127.0.0.1, their
// threads at SCHED_FIFO 75, the rig's I/O threads at 70): on the in-process loopback bus, or on
// a SocketCAN interface (vcan0 in the qemu VM of run-on-vcan.sh). Its watchdog is set out of reach
// (the benchmark measures; stale periods are counted and printed).
// --compensator: the adaptive run with another registered compensator at its defaults (as
// BM_Step/tracking_adaptive does), e.g. `tracking` against the default `robust` (issue 42).
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/rt/plant_service.hpp"
#include "hil/drv/can_loopback.hpp"
#include "hil/drv/cia402_emulator.hpp"
#include "hil/drv/modbus_emulator.hpp"
#include "hil/bench/rt/rig_config.hpp"
#include "hil/bench/rt/rt_thread.hpp"
#include "hil/bench/server/runner.hpp"
#include "hil/json_file.hpp"
#include "hil/text_file.hpp"

using namespace hil::bench;

namespace {

std::string replace(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  if (at == std::string::npos) throw std::runtime_error("paper_adaptive.yaml has no '" + from + "'");
  return text.replace(at, from.size(), to);
}

// The simulator side of the CAN rig, in this process.
struct CanChain {
  CanChain(const Campaign& c, const std::string& iface, const hil::drv::CanTransportFactory& bus)
      : raised(std::in_place, 75),
        plant(config(c)),
        drive(emulator(iface), plant.add_drive(), bus),
        transducer(link(), hil::drv::RegisterMap::load(HIL_SOURCE_DIR "/drivers/configs/modbus_transducer_map.yaml"),
                   plant.transducer()) {
    plant.start();
    raised.reset();
  }
  static PlantServiceConfig config(const Campaign& c) {
    PlantServiceConfig p;
    p.plant = c.plant;
    p.period_s = 1e-3;
    p.p_initial_pa = c.reference_pa.at(0.0);
    p.seed = c.seed;
    p.gap_program = c.gap_rad;
    p.rt_priority = 75;
    return p;
  }
  static hil::drv::Cia402EmulatorConfig emulator(const std::string& iface) {
    auto e = hil::drv::Cia402EmulatorConfig::load(HIL_SOURCE_DIR "/drivers/configs/cia402_emulator.yaml");
    e.interface = iface;
    return e;
  }
  static hil::drv::ModbusLinkConfig link() {
    hil::drv::ModbusLinkConfig l;
    l.host = "127.0.0.1";
    l.port = 0;
    return l;
  }
  // The rig file: configs/rigs/can.yaml's devices on this chain.
  std::string rig_yaml(const std::string& iface) const {
    return "kind: can\ndescription: benchmark\ndevices:\n"
           "  drive:\n    cia402: {interface: " +
           iface +
           ", node_id: 5, units: {counts_per_rev: 131072}}\n"
           "  transducer:\n    modbus: {link: {transport: tcp, host: 127.0.0.1, port: " +
           std::to_string(transducer.port()) +
           ", poll_period_ms: 2}, register_map: " HIL_SOURCE_DIR
           "/drivers/configs/modbus_transducer_map.yaml}\n"
           "    max_age_ms: 4\n"
           "loop: {priority: 80, cpu: 1, io_priority: 70}\n"
           "safety: {cmd_min_deg: -5, cmd_max_deg: 35, rate_limit_deg_s: 10000, p_max_mpa: 2.5, p_min_mpa: 0.2,\n"
           "         watchdog_misses: 1000000, safe_state: hold}\n";
  }
  std::optional<ScopedRealtime> raised;
  PlantService plant;
  hil::drv::Cia402DriveEmulator drive;
  hil::drv::ModbusTransducerEmulator transducer;
};

}  // namespace

int run(int argc, char** argv) {
  double hz = 1000, seconds = 60;
  int priority = 80, cpu = 1;
  std::string rig_file = HIL_SOURCE_DIR "/configs/rigs/sim.yaml";
  std::string keep;         // keep the run folder here (telemetry.csv has every period's wake-up latency)
  std::string can;          // the CAN rig: "loopback" or a SocketCAN interface
  std::string compensator;  // empty: the campaign's own (robust)
  const auto usage = [] {
    std::fprintf(stderr,
                 "usage: bench_rt_loop [--hz N] [--seconds S] [--priority P] [--cpu C] [--rig FILE] [--keep DIR] [--can "
                 "loopback|IFACE] [--compensator NAME]\n");
    return 2;
  };
  // Every option takes a value: a lone word (`--help`, a value forgotten) is the usage, not a run.
  if (argc % 2 == 0) return usage();
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i], v = argv[i + 1];
    if (a == "--hz")
      hz = std::stod(v);
    else if (a == "--seconds")
      seconds = std::stod(v);
    else if (a == "--priority")
      priority = std::stoi(v);
    else if (a == "--cpu")
      cpu = std::stoi(v);
    else if (a == "--rig")
      rig_file = v;
    else if (a == "--keep")
      keep = v;
    else if (a == "--can")
      can = v;
    else if (a == "--compensator")
      compensator = v;
    else
      return usage();
  }
  // paper_adaptive, stretched to the benchmark's length and rate.
  const std::string text = hil::read_text_file(HIL_SOURCE_DIR "/configs/campaigns/paper_adaptive.yaml");
  char period[32], duration[32];
  std::snprintf(period, sizeof period, "period_ms: %g", 1000.0 / hz);
  std::snprintf(duration, sizeof duration, "duration_s: %g", seconds);
  const std::string yaml = replace(replace(text, "period_ms: 1", period), "duration_s: 18", duration);

  StartRequest req;
  req.campaign = load_campaign_text(yaml, "paper_adaptive (benchmark)", HIL_SOURCE_DIR "/configs/campaigns");
  hil::drv::LoopbackBus bus;
  std::unique_ptr<CanChain> chain;
  const std::string iface = can == "loopback" ? "vcan0" : can;
  if (!can.empty()) {
    chain = std::make_unique<CanChain>(req.campaign, iface, can == "loopback" ? bus.factory() : hil::drv::CanTransportFactory{});
    rig_file = (std::filesystem::temp_directory_path() / ("hil_bench_rt_can_" + std::to_string(::getpid()) + ".yaml")).string();
    std::ofstream(rig_file) << chain->rig_yaml(iface);
  }
  req.rig = load_rig_config(rig_file);
  if (!can.empty()) std::filesystem::remove(rig_file);
  req.rig.loop.priority = priority;
  req.rig.loop.cpu = cpu;
  req.runs = {"adaptive"};
  if (!compensator.empty()) {
    for (auto& r : req.campaign.runs)
      if (r.name == "adaptive") {
        r.controller.compensator = compensator;
        r.controller.compensator_params.clear();  // its defaults
        r.controller.validate();                  // an unknown name is an error here, not in the loop
      }
  }
  req.source = "benchmark";

  const std::string mlock = lock_memory();
  const auto runs_dir = keep.empty() ? std::filesystem::temp_directory_path() / ("hil_bench_rt_" + std::to_string(::getpid()))
                                     : std::filesystem::path(keep);
  RunnerOptions ro;
  ro.runs_dir = runs_dir;
  ro.version = "benchmark";
  ro.mlock_warning = mlock;
  if (can == "loopback") ro.can_transport = bus.factory();
  {
    CampaignRunner runner(ro);
    runner.start(std::move(req));
    while (runner.running()) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    runner.wait();
  }
  std::filesystem::path dir;
  for (const auto& e : std::filesystem::directory_iterator(runs_dir)) dir = e.path();
  const nlohmann::json run = hil::read_json_file(dir / "run.json");
  const auto& loop = run["loop"];
  const auto& w = loop["wake_latency_us"];
  const auto& c = loop["compute_us"];
  if (!can.empty()) {
    std::printf(
        "CAN rig (%s): rig read us p50 %.2f p99 %.2f max %.1f | rig write us p50 %.2f p99 %.2f max %.1f | stale periods %lld\n",
        can.c_str(), loop["rig_read_us"]["p50_us"].get<double>(), loop["rig_read_us"]["p99_us"].get<double>(),
        loop["rig_read_us"]["max_us"].get<double>(), loop["rig_write_us"]["p50_us"].get<double>(),
        loop["rig_write_us"]["p99_us"].get<double>(), loop["rig_write_us"]["max_us"].get<double>(),
        loop["missed_reads"].get<long long>());
  }
  std::printf(
      "hilbench loop  %5.0f Hz %3.0f s  %s%s: wake-up latency us: min %.1f p50 %.1f p99 %.1f p99.9 %.1f max %.1f | "
      "compute us: p50 %.2f p99 %.2f max %.1f | overruns %lld (deadlines skipped %lld) in %lld periods | rows written %lld lost "
      "%lld | %s\n",
      hz, seconds, loop["sched"].get<std::string>().c_str(), mlock.empty() ? ", mlockall" : "", w["min_us"].get<double>(),
      w["p50_us"].get<double>(), w["p99_us"].get<double>(), w["p99_9_us"].get<double>(), w["max_us"].get<double>(),
      c["p50_us"].get<double>(), c["p99_us"].get<double>(), c["max_us"].get<double>(), loop["overruns"].get<long long>(),
      loop["skipped_deadlines"].get<long long>(), loop["periods"].get<long long>(),
      run["telemetry"]["rows_written"].get<long long>(), run["telemetry"]["rows_lost"].get<long long>(),
      run["outcome"].get<std::string>().c_str());
  if (keep.empty()) std::filesystem::remove_all(runs_dir);
  return run["telemetry"]["rows_lost"].get<long long>() == 0 && run["outcome"] == "completed" ? 0 : 1;
}

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_rt_loop: %s\n", e.what());
    return 1;
  }
}
