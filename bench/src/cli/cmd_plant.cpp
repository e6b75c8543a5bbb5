// hilbench plant --plant FILE [--can IFACE] [--modbus tcp:HOST:PORT] ...: the simulator side of
// the HIL. Runs the plant in real time behind a CiA 402 drive emulator on a CAN bus and/or a
// Modbus drive emulator (PORT) and a Modbus pressure transducer emulator (PORT + 1), until
// SIGINT/SIGTERM or --duration-s. Prints a status line every second.
// --campaign FILE takes the campaign's plant (with its sensor noise), seed, period, initial
// reference and gap programme, so the plant is the one `hilbench sim` would run (options given
// as well win). --port-file F: once every emulator listens and the plant runs, F holds
// {"modbus_drive_port": N, "transducer_port": M} (0 without --modbus): the ready signal.
#include <charconv>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <thread>

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "commands.hpp"
#include "hil/output_path.hpp"
#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/rt/plant_service.hpp"
#include "hil/drv/cia402_emulator.hpp"
#include "hil/drv/modbus_emulator.hpp"
#include "hil/line_file.hpp"
#include "hil/units.hpp"

namespace hil::bench {
namespace {

std::atomic<bool> g_stop{false};
extern "C" void on_signal(int) { g_stop = true; }

// "tcp:HOST:PORT" -> the drive emulator's link (the transducer's is PORT + 1). PORT is the whole
// text as a number 0..65534: stoi took "12abc" as 12 and 70000 went on to a 16-bit 4464, and 65535
// left the transducer 65536, which became 0. 0 means any free ports (printed and in --port-file).
// HOST is checked by the emulators, which refuse anything but a numeric IPv4 address.
drv::ModbusLinkConfig tcp_link(const std::string& spec) {
  const auto a = spec.find(':'), b = spec.rfind(':');
  if (spec.rfind("tcp:", 0) != 0 || a == b) throw UsageError("--modbus wants tcp:HOST:PORT, got '" + spec + "'");
  drv::ModbusLinkConfig link;
  link.host = spec.substr(a + 1, b - a - 1);
  if (link.host.empty()) throw UsageError("--modbus: no HOST in '" + spec + "' (e.g. tcp:127.0.0.1:5020)");
  const std::string port = spec.substr(b + 1);
  const char* end = port.data() + port.size();
  const auto [stop, ec] = std::from_chars(port.data(), end, link.port);
  if (port.empty() || ec != std::errc{} || stop != end || link.port < 0 || link.port > 65534) {
    throw UsageError("--modbus: the PORT '" + port +
                     "' is not a whole number 0..65534 (the transducer takes PORT + 1; 0: any free ports)");
  }
  return link;
}

struct PlantArgs {
  std::string plant_file = "configs/plant/nominal.yaml";
  std::string campaign_file, gap_program_file;  // empty: none
  std::string can_interface, modbus;            // empty: no such emulator
  std::string can_config = "drivers/configs/cia402_emulator.yaml";
  std::string drive_map = "drivers/configs/modbus_drive_map.yaml";
  std::string transducer_map = "drivers/configs/modbus_transducer_map.yaml";
  // These count only when given (their Option's count): otherwise the --can-config's node, and the
  // campaign's (or the plant service's default) period, initial pressure and seed.
  int node_id = 1;
  double period_ms = 1, initial_mpa = 1;
  std::uint64_t seed = 0;
  const CLI::Option *node_id_opt = nullptr, *period_opt = nullptr, *initial_opt = nullptr, *seed_opt = nullptr;
  double duration_s = 0;  // 0: until SIGINT/SIGTERM
  int rt_priority = 0, cpu = -1;
  std::string port_file;  // empty: none
  bool quiet = false;
};

int run_plant(const PlantArgs& args) {
  if (args.can_interface.empty() && args.modbus.empty()) throw UsageError("give --can IFACE and/or --modbus tcp:HOST:PORT");
  if (!args.port_file.empty()) check_output_file("--port-file", args.port_file, {}, "the port file");
  // Before the plant is loaded: a bad endpoint is refused before anything starts.
  const std::optional<drv::ModbusLinkConfig> modbus_link =
      args.modbus.empty() ? std::nullopt : std::optional(tcp_link(args.modbus));
  PlantServiceConfig config;
  std::string plant_name = args.plant_file;
  if (!args.campaign_file.empty()) {
    const Campaign c = load_campaign(args.campaign_file);
    plant_name = "campaign " + c.name + " (" + c.plant_file.string() + ")";
    config.plant = c.plant;
    config.period_s = c.period_s;
    config.p_initial_pa = c.reference_pa.at(0.0);
    config.seed = c.seed;
    config.gap_program = c.gap_rad;
  } else {
    config.plant = std::make_shared<const plant::Plant>(plant::Plant::load(plant_name));
  }
  if (args.period_opt->count() > 0) config.period_s = args.period_ms * 1e-3;
  if (args.initial_opt->count() > 0) config.p_initial_pa = units::mpa_to_pa(args.initial_mpa);
  if (args.seed_opt->count() > 0) config.seed = args.seed;
  config.rt_priority = args.rt_priority;
  config.cpu = args.cpu;
  if (!args.gap_program_file.empty()) config.gap_program = load_campaign(args.gap_program_file).gap_rad;
  const double config_period_ms = config.period_s * 1e3;
  PlantService service(std::move(config));

  // Emulators, each on its own thread, all backed by the one plant. With --rt-priority their
  // threads run SCHED_FIFO too (they inherit it from this thread while it lasts), so they answer
  // at once, as a device would.
  std::optional<ScopedRealtime> io_sched(std::in_place, args.rt_priority);
  if (!io_sched->warning().empty()) spdlog::warn("plant: {}", io_sched->warning());
  std::unique_ptr<drv::Cia402DriveEmulator> can;
  std::unique_ptr<drv::ModbusDriveEmulator> mb_drive;
  std::unique_ptr<drv::ModbusTransducerEmulator> mb_pressure;
  if (!args.can_interface.empty()) {
    auto cfg = drv::Cia402EmulatorConfig::load(args.can_config);
    cfg.interface = args.can_interface;
    if (args.node_id_opt->count() > 0) cfg.node_id = static_cast<std::uint8_t>(args.node_id);
    can = std::make_unique<drv::Cia402DriveEmulator>(cfg, service.add_drive());
  }
  if (modbus_link) {
    const drv::ModbusLinkConfig& drive = *modbus_link;
    drv::ModbusLinkConfig pressure = drive;
    pressure.port = drive.port == 0 ? 0 : drive.port + 1;
    mb_drive = std::make_unique<drv::ModbusDriveEmulator>(drive, drv::RegisterMap::load(args.drive_map), service.add_drive());
    mb_pressure = std::make_unique<drv::ModbusTransducerEmulator>(pressure, drv::RegisterMap::load(args.transducer_map),
                                                                  service.transducer());
  }
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  service.start();
  io_sched.reset();
  std::printf("plant: %s, period %.3g ms, %s\n", plant_name.c_str(), config_period_ms, service.rt().describe().c_str());
  if (can) std::printf("plant: CiA 402 drive on %s\n", args.can_interface.c_str());
  if (mb_drive)
    std::printf("plant: Modbus drive on tcp port %d, transducer on tcp port %d\n", mb_drive->port(), mb_pressure->port());
  if (!args.port_file.empty()) {
    hil::replace_file(args.port_file, nlohmann::json{{"modbus_drive_port", mb_drive ? mb_drive->port() : 0},
                                                     {"transducer_port", mb_pressure ? mb_pressure->port() : 0}}
                                              .dump() +
                                          "\n");  // appears complete or not at all
  }
  std::printf("plant: ready\n");
  std::fflush(stdout);

  const double duration_s = args.duration_s;
  const auto t0 = Clock::now();
  while (!g_stop) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
    static double last_print = 0;
    if (!args.quiet && wall - last_print >= 1.0) {
      last_print = wall;
      const PlantSample s = service.sample();
      std::printf("t %8.2f s  Pg %.4f MPa  motor %7.3f deg  valve %7.3f deg  gap %.3f deg  %s  late steps %llu\n", s.t_s,
                  units::pa_to_mpa(s.p_meas_pa), units::rad_to_deg(s.theta_motor_rad), units::rad_to_deg(s.theta_valve_rad),
                  units::rad_to_deg(s.gap_rad), s.enabled ? "enabled" : "disabled",
                  static_cast<unsigned long long>(s.late_steps));
      std::fflush(stdout);
    }
    if (duration_s > 0 && wall >= duration_s) break;
  }
  service.stop();
  std::printf("plant: stopped\n");
  return 0;
}

}  // namespace

CommandRun define_plant(CLI::App& cmd) {
  auto args = std::make_shared<PlantArgs>();
  auto* plant_opt = cmd.add_option("--plant", args->plant_file, "the plant")->type_name("FILE")->capture_default_str();
  auto* campaign_opt =
      cmd.add_option("--campaign", args->campaign_file, "the campaign's plant, seed, period, initial pressure and gap programme")
          ->type_name("CAMPAIGN.yaml");
  campaign_opt->excludes(plant_opt);
  cmd.add_option("--can", args->can_interface, "a CiA 402 drive emulator on this CAN interface")->type_name("IFACE");
  args->node_id_opt = cmd.add_option("--node-id", args->node_id, "its CANopen node (default: the --can-config's)")
                          ->type_name("N")
                          ->check(whole_number(1, 127));
  cmd.add_option("--can-config", args->can_config, "the CiA 402 emulator's configuration")
      ->type_name("FILE")
      ->capture_default_str();
  cmd.add_option("--modbus", args->modbus, "a Modbus drive emulator on PORT, the transducer's on PORT + 1")
      ->type_name("tcp:HOST:PORT");
  cmd.add_option("--drive-map", args->drive_map, "the Modbus drive's register map")->type_name("FILE")->capture_default_str();
  cmd.add_option("--transducer-map", args->transducer_map, "the Modbus transducer's register map")
      ->type_name("FILE")
      ->capture_default_str();
  args->period_opt = cmd.add_option("--period-ms", args->period_ms, "the plant's step (default: the campaign's, or 1)")
                         ->type_name("MS")
                         ->check(number_in(kMinPeriodMs, kMaxPeriodMs));  // a campaign's range
  args->initial_opt = cmd.add_option("--initial-mpa", args->initial_mpa, "the initial pressure (default: the campaign's, or 1.0)")
                          ->type_name("MPA")
                          ->check(finite_number());
  cmd.add_option("--gap-program", args->gap_program_file, "the gap programme of this campaign")->type_name("CAMPAIGN.yaml");
  args->seed_opt = cmd.add_option("--seed", args->seed, "the noise seed (default: the campaign's)")
                       ->type_name("N")
                       ->check(whole_number(0, INT64_MAX));
  cmd.add_option("--duration-s", args->duration_s, "stop after this long (0: at SIGINT/SIGTERM)")
      ->type_name("S")
      ->check(non_negative_number());
  cmd.add_option("--rt-priority", args->rt_priority, "SCHED_FIFO priority of the plant and emulators (0: none)")
      ->type_name("P")
      ->check(whole_number(0, 99));
  cmd.add_option("--cpu", args->cpu, "pin the plant's thread to this CPU (-1: none)")
      ->type_name("N")
      ->check(whole_number(-1, 4095));
  cmd.add_option("--port-file", args->port_file, "write the Modbus ports there once ready (the ready signal)")->type_name("F");
  cmd.add_flag("--quiet", args->quiet, "no status line every second");
  return [args] { return run_plant(*args); };
}

}  // namespace hil::bench
