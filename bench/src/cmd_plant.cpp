// hilbench plant --plant FILE [--can IFACE] [--modbus tcp:HOST:PORT] ...: the simulator side of
// the HIL. Runs the plant in real time behind a CiA 402 drive emulator on a CAN bus and/or a
// Modbus drive emulator (PORT) and a Modbus pressure transducer emulator (PORT + 1), until
// SIGINT/SIGTERM or --duration-s. Prints a status line every second.
// --campaign FILE takes the campaign's plant (with its sensor noise), seed, period, initial
// reference and gap programme, so the plant is the one `hilbench sim` would run (options given
// as well win). --port-file F: once every emulator listens and the plant runs, F holds
// {"modbus_drive_port": N, "transducer_port": M} (0 without --modbus): the ready signal.
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <thread>

#include <nlohmann/json.hpp>

#include "cli.hpp"
#include "commands.hpp"
#include "hil/bench/campaign.hpp"
#include "hil/bench/plant_service.hpp"
#include "hil/drv/cia402_emulator.hpp"
#include "hil/drv/modbus_emulator.hpp"
#include "hil/units.hpp"

namespace hil::bench {
namespace {

std::atomic<bool> g_stop{false};
extern "C" void on_signal(int) { g_stop = true; }

// "tcp:HOST:PORT" -> link config.
drv::ModbusLinkConfig tcp_link(const std::string& spec) {
  const auto a = spec.find(':'), b = spec.rfind(':');
  if (spec.rfind("tcp:", 0) != 0 || a == b) throw UsageError("--modbus wants tcp:HOST:PORT, got '" + spec + "'");
  drv::ModbusLinkConfig link;
  link.host = spec.substr(a + 1, b - a - 1);
  try {
    link.port = std::stoi(spec.substr(b + 1));
  } catch (const std::exception&) {
    throw UsageError("--modbus: '" + spec.substr(b + 1) + "' is not a port number");
  }
  return link;
}

}  // namespace

int cmd_plant(const std::vector<std::string>& argv) {
  const Args args = parse_args(argv,
                               {"plant", "campaign", "can", "node-id", "can-config", "modbus", "drive-map", "transducer-map",
                                "period-ms", "initial-mpa", "gap-program", "seed", "duration-s", "rt-priority", "cpu",
                                "port-file"},
                               {"quiet"});
  if (!args.positional.empty()) throw UsageError("plant takes options only");
  if (!args.options.count("can") && !args.options.count("modbus")) throw UsageError("give --can IFACE and/or --modbus tcp:HOST:PORT");

  if (args.options.count("plant") && args.options.count("campaign")) throw UsageError("give --plant or --campaign, not both");
  PlantServiceConfig config;
  std::string plant_name = args.option("plant", "configs/plant/nominal.yaml");
  if (args.options.count("campaign")) {
    const Campaign c = load_campaign(args.option("campaign", ""));
    plant_name = "campaign " + c.name + " (" + c.plant_file.string() + ")";
    config.plant = c.plant;
    config.period_s = c.period_s;
    config.p_initial_pa = c.reference_pa.at(0.0);
    config.seed = c.seed;
    config.gap_program = c.gap_rad;
  } else {
    config.plant = std::make_shared<const plant::Plant>(plant::Plant::load(plant_name));
  }
  config.period_s = args.number("period-ms", config.period_s * 1e3) * 1e-3;
  config.p_initial_pa = units::mpa_to_pa(args.number("initial-mpa", units::pa_to_mpa(config.p_initial_pa)));
  config.seed = static_cast<std::uint64_t>(args.number("seed", static_cast<double>(config.seed)));
  config.rt_priority = static_cast<int>(args.number("rt-priority", 0));
  config.cpu = static_cast<int>(args.number("cpu", -1));
  if (args.options.count("gap-program")) config.gap_program = load_campaign(args.option("gap-program", "")).gap_rad;
  const double config_period_ms = config.period_s * 1e3;
  PlantService service(std::move(config));

  // Emulators, each on its own thread, all backed by the one plant. With --rt-priority their
  // threads run SCHED_FIFO too (they inherit it from this thread while it lasts), so they answer
  // at once, as a device would.
  std::optional<ScopedRealtime> io_sched(std::in_place, static_cast<int>(args.number("rt-priority", 0)));
  if (!io_sched->warning().empty()) std::fprintf(stderr, "plant: %s\n", io_sched->warning().c_str());
  std::unique_ptr<drv::Cia402DriveEmulator> can;
  std::unique_ptr<drv::ModbusDriveEmulator> mb_drive;
  std::unique_ptr<drv::ModbusTransducerEmulator> mb_pressure;
  if (args.options.count("can")) {
    auto cfg = drv::Cia402EmulatorConfig::load(args.option("can-config", "drivers/configs/cia402_emulator.yaml"));
    cfg.interface = args.option("can", "vcan0");
    if (args.options.count("node-id")) cfg.node_id = static_cast<std::uint8_t>(args.number("node-id", 1));
    can = std::make_unique<drv::Cia402DriveEmulator>(cfg, service.add_drive());
  }
  if (args.options.count("modbus")) {
    drv::ModbusLinkConfig drive = tcp_link(args.option("modbus", ""));
    drv::ModbusLinkConfig pressure = drive;
    pressure.port = drive.port == 0 ? 0 : drive.port + 1;
    mb_drive = std::make_unique<drv::ModbusDriveEmulator>(
        drive, drv::RegisterMap::load(args.option("drive-map", "drivers/configs/modbus_drive_map.yaml")), service.add_drive());
    mb_pressure = std::make_unique<drv::ModbusTransducerEmulator>(
        pressure, drv::RegisterMap::load(args.option("transducer-map", "drivers/configs/modbus_transducer_map.yaml")),
        service.transducer());
  }
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  service.start();
  io_sched.reset();
  std::printf("plant: %s, period %.3g ms, %s\n", plant_name.c_str(), config_period_ms, service.rt().describe().c_str());
  if (can) std::printf("plant: CiA 402 drive on %s\n", args.option("can", "").c_str());
  if (mb_drive) std::printf("plant: Modbus drive on tcp port %d, transducer on tcp port %d\n", mb_drive->port(), mb_pressure->port());
  if (args.options.count("port-file")) {
    const std::filesystem::path file = args.option("port-file", "");
    const auto tmp = file.string() + ".tmp";
    std::ofstream(tmp) << nlohmann::json{{"modbus_drive_port", mb_drive ? mb_drive->port() : 0},
                                         {"transducer_port", mb_pressure ? mb_pressure->port() : 0}}.dump()
                       << "\n";
    std::filesystem::rename(tmp, file);  // appears complete or not at all
  }
  std::printf("plant: ready\n");
  std::fflush(stdout);

  const double duration_s = args.number("duration-s", 0);
  const auto t0 = Clock::now();
  while (!g_stop) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
    static double last_print = 0;
    if (!args.has("quiet") && wall - last_print >= 1.0) {
      last_print = wall;
      const PlantSample s = service.sample();
      std::printf("t %8.2f s  Pg %.4f MPa  motor %7.3f deg  valve %7.3f deg  gap %.3f deg  %s  late steps %llu\n",
                  s.t_s, units::pa_to_mpa(s.p_meas_pa), units::rad_to_deg(s.theta_motor_rad),
                  units::rad_to_deg(s.theta_valve_rad), units::rad_to_deg(s.gap_rad), s.enabled ? "enabled" : "disabled",
                  static_cast<unsigned long long>(s.late_steps));
      std::fflush(stdout);
    }
    if (duration_s > 0 && wall >= duration_s) break;
  }
  service.stop();
  std::printf("plant: stopped\n");
  return 0;
}

}  // namespace hil::bench
