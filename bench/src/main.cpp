// hilbench: one executable, one sub-command per job.
#include <algorithm>
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "cli.hpp"
#include "commands.hpp"
#include "hil/config.hpp"
#include "hil/csv_reader.hpp"

namespace {

struct Command {
  const char* name;
  int (*run)(const std::vector<std::string>&);
  const char* usage;
};

const Command kCommands[] = {
    {"sim", hil::bench::cmd_sim,
     "sim CAMPAIGN.yaml [--out DIR] [--runs a,b] [--sensor-noise-kpa X] [--no-telemetry] [--quiet]\n"
     "      run a campaign on the simulated plant, faster than real time"},
    {"effects", hil::bench::cmd_effects, "effects\n      list the physical effects a plant file may use"},
    {"serve", hil::bench::cmd_serve,
     "serve [--listen HOST:PORT] [--token T] [--configs DIR] [--runs-dir DIR] [--port-file F] [--no-mlock]\n"
     "      the bench server: real-time loop, operator API (HTTP/JSON, WebSocket telemetry)"},
    {"ctl", hil::bench::cmd_ctl,
     "ctl [--server URL] [--token T] status|campaigns|rigs|runs|start|watch|stop|abort|inject|telemetry|show|get ...\n"
     "      command-line client of hilbench serve (hilbench ctl --help)"},
    {"compare", hil::bench::cmd_compare,
     "compare --model MODEL.yaml --data FILE.csv [--out DIR] [--quiet]\n"
     "      replay a measurement through a model and show where the model fails"},
    {"diagnose", hil::bench::cmd_diagnose,
     "diagnose --model MODEL.yaml --data FILE.csv [--data MORE.csv ...] [--out DIR] [--write-model FITTED.yaml]\n"
     "         [--candidates a,b] [--threads N] [--quiet]\n"
     "      find the missing physical effect: fit each candidate, rank them, add the ones that earn their place;\n"
     "      several --data files (runs of one rig) are fitted together with shared parameters"},
    {"plant", hil::bench::cmd_plant,
     "plant [--plant FILE | --campaign CAMPAIGN.yaml] [--can IFACE] [--modbus tcp:HOST:PORT] [--gap-program CAMPAIGN.yaml]\n"
     "      [--period-ms 1] [--initial-mpa 1.0] [--duration-s S] [--rt-priority P] [--port-file F]\n"
     "      the simulator side of the HIL: the plant in real time behind emulated CAN and Modbus devices"},
    {"report", hil::bench::cmd_report,
     "report RUN_DIR... [--out FILE] [--quiet]\n"
     "      the paper-style report of runs recorded by hilbench serve (default FILE: the first RUN_DIR/report.html)"},
    {"drive", hil::bench::cmd_drive,
     "drive probe --rig FILE\n"
     "      know the rig's CiA 402 drive before a run: identity, modes, objects, PDOs, limits (no motion)"},
    {"characterise", hil::bench::cmd_characterise,
     "characterise [--readme README.md] [--campaigns DIR]\n"
     "      the observers on the paper's scenarios, noise-free and noisy, as a markdown table"},
};

void usage(std::FILE* to) {
  std::fprintf(to, "usage: hilbench <command> [arguments]\n\ncommands:\n");
  for (const auto& c : kCommands) std::fprintf(to, "  %s\n", c.usage);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h") {
    usage(argc < 2 ? stderr : stdout);
    return argc < 2 ? 2 : 0;
  }
  const std::string name = argv[1];
  if (name == "--version") {
    std::printf("hilbench %s\n", HIL_VERSION);
    return 0;
  }
  std::vector<std::string> args(argv + 2, argv + argc);
  std::vector<std::string> names;
  for (const auto& c : kCommands) {
    names.emplace_back(c.name);
    if (name != c.name) continue;
    // `hilbench X --help`: X's usage on stdout, exit 0 (ctl has sub-commands and its own help).
    if (name == "ctl" && !args.empty() && args[0] == "-h") args[0] = "--help";
    if (name != "ctl" && std::any_of(args.begin(), args.end(), [](const std::string& a) { return a == "--help" || a == "-h"; })) {
      std::printf("usage: hilbench %s\n", c.usage);
      return 0;
    }
    try {
      return c.run(args);
    } catch (const hil::bench::UsageError& e) {
      std::fprintf(stderr, "hilbench %s: %s\nusage: hilbench %s\n", c.name, e.what(), c.usage);
      return 2;
    } catch (const hil::cfg::Error& e) {
      std::fprintf(stderr, "hilbench %s: %s\n", c.name, e.what());
      return 1;
    } catch (const hil::CsvError& e) {
      std::fprintf(stderr, "hilbench %s: %s\n", c.name, e.what());
      return 1;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "hilbench %s: error: %s\n", c.name, e.what());
      return 1;
    }
  }
  const std::string hint = hil::cfg::closest(name, names);
  std::fprintf(stderr, "hilbench: unknown command '%s'%s\n\n", name.c_str(),
               hint.empty() ? "" : (" (did you mean '" + hint + "'?)").c_str());
  usage(stderr);
  return 2;
}
