// Fuzz target "cia402_emulator": the bytes as CAN frames from any node on the bus into the CiA 402
// drive emulator (hil::drv::Cia402DriveEmulator, what `hilbench plant` runs behind CAN): NMT
// commands, SYNC, SDO requests (reads and writes of its dictionary: heartbeat, PDO communication
// and mapping, mode, controlword, target), RPDOs on the four default COB-IDs, and other ids. A
// bench's client is one node on that bus; a misconfigured tool or a second master is another.
// An emulator is made for each input, its boot included, so a finding replays alone. It must
// take every frame without throwing out of its I/O thread (that is std::terminate: the whole
// plant process gone) and still answer, with the frames handled in order, at the end.
// Input: records of 11 bytes, [kind] [dlc] [8 data bytes] [id]; kind & 7 picks the COB-ID for
// node 5 (0 NMT, 1 SYNC, 2 SDO request, 3..6 RPDO1..4, 7 the raw 11-bit id (kind >> 5) << 8 | id),
// kind & 8 = RTR. The dlc byte is taken modulo 16 (the emulator must not trust it).
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>

#include "hil/drv/can_loopback.hpp"
#include "hil/drv/canopen.hpp"
#include "hil/drv/cia402_emulator.hpp"
#include "servo_test_model.hpp"

namespace {

using namespace hil::drv;
constexpr std::uint8_t kNode = 5;
constexpr std::size_t kRecord = 11;

CanFrame frame(const std::uint8_t* r) {
  CanFrame f;
  f.rtr = (r[0] & 8) != 0;
  f.dlc = static_cast<std::uint8_t>(r[1] % 16);
  for (int i = 0; i < 8; ++i) f.data[static_cast<std::size_t>(i)] = r[2 + i];
  switch (r[0] & 7) {
    case 0: f.id = canopen::kNmt; break;
    case 1: f.id = canopen::kSync; break;
    case 2: f.id = canopen::kSdoRx + kNode; break;
    case 7: f.id = ((static_cast<std::uint32_t>(r[0]) >> 5) << 8 | r[10]) & 0x7FF; break;
    default: f.id = canopen::kRpdo1 + 0x100u * static_cast<std::uint32_t>((r[0] & 7) - 3) + kNode; break;
  }
  return f;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  LoopbackBus bus;
  FirstOrderServoTestModel model(0.01, 20.0, 0.25);
  Cia402EmulatorConfig cfg;
  cfg.node_id = kNode;
  cfg.pdos = 4;  // every object the emulator can have, so every path is reachable
  cfg.following_error = true;
  cfg.quick_stop_ramp = true;
  Cia402DriveEmulator emulator(cfg, model, bus.factory("fuzz"));
  for (std::size_t at = 0; at + kRecord <= size; at += kRecord) bus.inject(frame(data + at));
  // A read of the dictionary runs on the emulator's I/O thread after every frame above (posted in
  // order): it answers only if that thread is alive, and the device type never changes.
  if (emulator.object(0x1000, 0) != 0x00020192u) {
    std::fprintf(stderr, "\nFINDING: the emulator's device type 0x1000 changed or is gone\n");
    std::abort();
  }
  return 0;
}
