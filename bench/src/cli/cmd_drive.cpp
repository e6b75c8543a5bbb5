// hilbench drive probe --rig FILE: know a drive before a run. Connects to the rig's CiA 402 drive,
// reads what it is and what it has over SDO (identity 0x1018, supported modes 0x6502, the objects
// the client uses, PDO counts, the following error window) and prints what the rig will do with
// it and what it lacks. Sends no NMT command, no SYNC and no controlword: the motor does not move.
#include <cstdio>
#include <memory>
#include <string>

#include "commands.hpp"
#include "hil/bench/rt/rig_config.hpp"
#include "hil/drv/cia402_drive.hpp"
#include "hil/drv/cia402_probe.hpp"
#include "hil/drv/sdo_client.hpp"

namespace hil::bench {

namespace {

int run_probe(const std::string& rig_file) {
  const RigConfig rig = load_rig_config(rig_file);
  const drv::Cia402Config* drive = rig.devices.drive_config<drv::Cia402Config>();
  if (drive == nullptr) {
    std::fprintf(stderr, "hilbench drive probe: rig '%s' has no CiA 402 drive (probe reads CANopen drives)\n", rig.name.c_str());
    return 1;
  }
  // The SDO client alone, on a channel of its own: no SYNC, PDO or heartbeat goes out.
  drv::SdoChannel channel(drive->interface,
                          {.node_id = drive->node_id,
                           .who = "CiA 402 drive node " + std::to_string(drive->node_id) + " on " + drive->interface,
                           .timeout = drive->sdo_timeout,
                           .retries = drive->sdo_retries});
  std::printf("CiA 402 drive node %u on %s (rig '%s', %s)\n", drive->node_id, drive->interface.c_str(), rig.name.c_str(),
              rig.file.string().c_str());
  const drv::Cia402Probe p = drv::probe(channel.sdo(), *drive);
  std::fputs(p.report().c_str(), stdout);
  return p.usable ? 0 : 1;
}

}  // namespace

CommandRun define_drive(CLI::App& cmd) {
  cmd.require_subcommand(1);
  CLI::App* probe = add_command(cmd, "probe", "read what the drive is and has over SDO; the motor does not move");
  probe->footer(
      "Reads the CiA 402 drive of rig FILE (configs/rigs/*.yaml, kind can or hybrid) over SDO: identity\n"
      "(0x1018), supported modes (0x6502), which objects the client uses it has, PDO counts, the following\n"
      "error window (0x6065/0x6066), and prints what the rig will do with this drive and what it lacks.\n"
      "No NMT start, no SYNC, no enable: the motor does not move. Exit code 0 usable, 1 not usable or no answer.");
  auto rig_file = std::make_shared<std::string>();
  probe->add_option("--rig", *rig_file, "the rig file")->required()->type_name("FILE");
  return [rig_file] { return run_probe(*rig_file); };
}

}  // namespace hil::bench
