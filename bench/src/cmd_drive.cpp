// hilbench drive probe --rig FILE: know a drive before a run. Connects to the rig's CiA 402 drive,
// reads what it is and what it has over SDO (identity 0x1018, supported modes 0x6502, the objects
// the client uses, PDO counts, the following error window) and prints what the rig will do with
// it and what it lacks. Sends no NMT command, no SYNC and no controlword: the motor does not move.
#include <cstdio>
#include <string>

#include "cli.hpp"
#include "commands.hpp"
#include "hil/bench/rig_config.hpp"
#include "hil/drv/cia402_drive.hpp"
#include "hil/drv/cia402_probe.hpp"

namespace hil::bench {

namespace {
constexpr const char* kUsage =
    "usage: hilbench drive probe --rig FILE\n"
    "  Reads the CiA 402 drive of rig FILE (configs/rigs/*.yaml, kind can or hybrid) over SDO: identity\n"
    "  (0x1018), supported modes (0x6502), which objects the client uses it has, PDO counts, the following\n"
    "  error window (0x6065/0x6066), and prints what the rig will do with this drive and what it lacks.\n"
    "  No NMT start, no SYNC, no enable: the motor does not move. Exit code 0 usable, 1 not usable or no answer.\n";
}  // namespace

int cmd_drive(const std::vector<std::string>& argv) {
  if (argv.empty() || argv[0] == "--help" || argv[0] == "-h") {
    std::fputs(kUsage, argv.empty() ? stderr : stdout);
    return argv.empty() ? 2 : 0;
  }
  if (argv[0] != "probe") throw UsageError("unknown drive command '" + argv[0] + "' (probe)");
  const std::vector<std::string> rest(argv.begin() + 1, argv.end());
  for (const auto& a : rest) {
    if (a == "--help" || a == "-h") {
      std::fputs(kUsage, stdout);
      return 0;
    }
  }
  const Args args = parse_args(rest, {"rig"}, {});
  if (!args.positional.empty()) throw UsageError("drive probe takes --rig FILE only");
  if (!args.options.count("rig")) throw UsageError("give --rig FILE");
  const RigConfig rig = load_rig_config(args.option("rig", ""));
  if (!rig.devices.can_drive) {
    std::fprintf(stderr, "hilbench drive probe: rig '%s' has no CiA 402 drive (probe reads CANopen drives)\n", rig.name.c_str());
    return 1;
  }
  drv::Cia402Drive client(*rig.devices.can_drive);
  std::printf("CiA 402 drive node %u on %s (rig '%s', %s)\n", rig.devices.can_drive->node_id,
              rig.devices.can_drive->interface.c_str(), rig.name.c_str(), rig.file.string().c_str());
  const drv::Cia402Probe p = drv::probe(client);
  std::fputs(p.report().c_str(), stdout);
  return p.usable ? 0 : 1;
}

}  // namespace hil::bench
