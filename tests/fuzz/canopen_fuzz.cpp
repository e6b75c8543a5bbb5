// Fuzz target "canopen": the bytes as a sequence of CAN frames received from a CiA 402 drive.
//   1. Every frame goes through the pure decoders of drivers/ (hil/drv/canopen.hpp, can.hpp):
//      SDO reply, EMCY (and its text), error-frame decoding and the bus-state tracker, the
//      statusword state machine and the controlword it asks for, candump text.
//   2. Frames on the drive's own COB-IDs (heartbeat, TPDO1, SDO reply, EMCY) and error frames are
//      injected into a hil::drv::Cia402Drive (the real client, I/O thread included) on an
//      in-process loopback bus; the target waits until the client has taken every frame in.
// Input: records of 14 bytes, [kind] [id: 4 bytes LE] [dlc] [8 data bytes]; kind & 7 picks the
// COB-ID (0 heartbeat, 1 TPDO1, 2 SDO reply, 3 EMCY of node 5, 4 error frame, else the raw id,
// decoders only), kind & 8 = RTR. The dlc byte is taken modulo 16 (a CAN FD length nibble: the
// decoders must not trust it). No clear errors here: a decoder reports malformed frames by value.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <thread>

#include "fuzz_support.hpp"
#include "hil/drv/can.hpp"
#include "hil/drv/can_loopback.hpp"
#include "hil/drv/canopen.hpp"
#include "hil/drv/cia402_drive.hpp"

namespace {

using namespace hil::drv;
constexpr std::uint8_t kNode = 5;
constexpr std::size_t kRecord = 14;

struct Client {
  LoopbackBus bus;
  std::unique_ptr<Cia402Drive> drive;
  Client() {
    Cia402Config cfg;
    cfg.node_id = kNode;
    cfg.sync_period = std::chrono::seconds(1);  // quiet: the target drives the traffic
    drive = std::make_unique<Cia402Drive>(cfg, bus.factory("fuzz"));
  }
  std::uint64_t taken() const {
    const auto h = drive->health();
    return h.rx_frames + h.error_frames;
  }
};

void decode(const CanFrame& f) {
  const auto sdo = canopen::parse_sdo_reply(f);
  if (sdo.kind == canopen::SdoReply::Kind::abort) (void)canopen::sdo_abort_name(sdo.value);
  (void)canopen::object_name(sdo.index, sdo.sub);
  if (const auto e = canopen::parse_emcy(f)) {
    (void)canopen::describe(*e);
    (void)canopen::emcy_class_name(e->error_code);
    const CanFrame back = canopen::emcy(kNode, *e);
    const auto again = canopen::parse_emcy(back);
    if (!again || again->error_code != e->error_code || again->error_register != e->error_register) {
      std::fprintf(stderr, "\nFINDING: EMCY does not survive encode/decode\n");
      std::abort();
    }
  }
  if (f.error) {
    const auto info = decode_error_frame(f);
    BusStateTracker tracker;
    (void)tracker.update(info);
  }
  const auto sw = static_cast<std::uint16_t>(canopen::get_le(f.data.data(), 2));
  const auto state = cia402::decode_statusword(sw);
  (void)cia402::to_string(state);
  for (auto target : {cia402::Target::disabled, cia402::Target::switched_on, cia402::Target::operation_enabled}) {
    (void)cia402::next_controlword(state, target, f.data[2] & 1);
  }
  (void)canopen::to_string(static_cast<canopen::NmtState>(f.data[0]));
  (void)to_string(f);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static Client client;
  const std::uint64_t before = client.taken();
  std::uint64_t injected = 0;
  for (std::size_t at = 0; at + kRecord <= size; at += kRecord) {
    const std::uint8_t* r = data + at;
    CanFrame f;
    const std::uint32_t raw = static_cast<std::uint32_t>(canopen::get_le(r + 1, 4));
    f.rtr = (r[0] & 8) != 0;
    f.dlc = static_cast<std::uint8_t>(r[5] % 16);
    for (int i = 0; i < 8; ++i) f.data[static_cast<std::size_t>(i)] = r[6 + i];
    bool inject = true;
    switch (r[0] & 7) {
      case 0: f.id = canopen::kHeartbeat + kNode; break;
      case 1: f.id = canopen::kTpdo1 + kNode; break;
      case 2: f.id = canopen::kSdoTx + kNode; break;
      case 3: f.id = canopen::kEmcy + kNode; break;
      case 4: f.error = true, f.rtr = false, f.id = raw & 0x1FFFFFFFu; break;
      default:
        inject = false;
        f.extended = (r[0] & 16) != 0;
        f.id = raw & (f.extended ? 0x1FFFFFFFu : 0x7FFu);
        break;
    }
    decode(f);
    if (inject) {
      client.bus.inject(f);
      ++injected;
    }
  }
  // Every injected frame must be taken in by the client's I/O thread (or it hangs or lost one).
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::seconds(8);  // below -timeout=10, generous on a busy machine
  while (client.taken() < before + injected) {
    if (std::chrono::steady_clock::now() > deadline) {
      std::fprintf(stderr, "\nFINDING: the CiA 402 client took %llu of %llu frames within 8 s\n",
                   static_cast<unsigned long long>(client.taken() - before), static_cast<unsigned long long>(injected));
      std::abort();
    }
    std::this_thread::yield();
  }
  return 0;
}
