// Fuzz target "canopen": the bytes as a sequence of CAN frames received from a CiA 402 drive.
//   1. Every frame goes through the pure decoders of drivers/ (hil/drv/canopen.hpp, can.hpp):
//      SDO reply, EMCY (and its text), error-frame decoding and the bus-state tracker, the
//      statusword state machine and the controlword it asks for, candump text.
//   2. Frames on the drive's own COB-IDs (heartbeat, TPDO1, SDO reply, EMCY) and error frames are
//      injected into a hil::drv::Cia402Drive (the real client, I/O thread included) on an
//      in-process loopback bus; the target waits until the client has taken every frame in.
//   3. The client's SDO path with a request in flight: a record of kind & 0x27 == 0x27 makes the
//      client read (kind & 0x40: write) an object, on a thread of its own, as configure() and
//      `hilbench drive` do; the frames after it are the drive's answers, matching or not. At the
//      end of the input the target answers the request with an abort (a stray reply if the
//      fuzzed frames ended it already) and joins: the read or write must have returned or thrown
//      the client's own DriveError/SdoAbortError, never anything else, and never hang.
// Input: records of 14 bytes, [kind] [id: 4 bytes LE] [dlc] [8 data bytes]; kind & 7 picks the
// COB-ID (0 heartbeat, 1 TPDO1, 2 SDO reply, 3 EMCY of node 5, 4 error frame, else the raw id,
// decoders only), kind & 8 = RTR. The dlc byte is taken modulo 16 (a CAN FD length nibble: the
// decoders must not trust it). An SDO request record: id bytes 0-1 the index, byte 2 the
// subindex; a write's value is the first 4 data bytes, its size (dlc % 4) + 1. Malformed frames
// are reported by value; the SDO calls' clear errors are DriveError and SdoAbortError.
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <optional>
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
  std::atomic<std::uint64_t> sdo_requests{0};  // SDO requests the client put on the bus (the tap's count)
  Client() {
    Cia402Config cfg;
    cfg.node_id = kNode;
    cfg.sync_period = std::chrono::seconds(1);  // quiet: the target drives the traffic
    bus.set_tap([this](const CanFrame& f) {
      if (f.id == canopen::kSdoRx + kNode && !f.error) sdo_requests.fetch_add(1);
    });
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

// Waits until the client has done what it must within 8 s (below -timeout=10, generous on a busy
// machine), or reports what it did not do.
template <class Done>
void await(Done&& done, const char* what) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(8);
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) {
      std::fprintf(stderr, "\nFINDING: the CiA 402 client %s within 8 s\n", what);
      std::abort();
    }
    std::this_thread::yield();
  }
}

// One SDO read or write of the client in flight, on its own thread (the calls block).
struct SdoCall {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::thread thread;
  SdoCall(Client& client, const std::uint8_t* record) {
    index = static_cast<std::uint16_t>(canopen::get_le(record + 1, 2));
    sub = record[3];
    const bool write = (record[0] & 0x40) != 0;
    const auto value = static_cast<std::uint32_t>(canopen::get_le(record + 6, 4));
    const auto size = static_cast<std::uint8_t>(record[5] % 4 + 1);
    const std::uint64_t sent = client.sdo_requests.load();
    thread = std::thread([&client, write, index = index, sub = sub, value, size] {
      hil::fuzz::expect_clear_errors<DriveError>("canopen: an SDO call", [&] {
        if (write)
          client.drive->sdo_write(index, sub, value, size);
        else
          (void)client.drive->sdo_read(index, sub);
      });
    });
    // The answers that follow are meant for a request on the bus.
    await([&] { return client.sdo_requests.load() > sent; }, "put no SDO request on the bus");
  }
  SdoCall(const SdoCall&) = delete;
  SdoCall& operator=(const SdoCall&) = delete;
  ~SdoCall() { thread.join(); }  // the call's own budget ends it at worst (a few seconds)
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static Client client;
  const std::uint64_t before = client.taken();
  std::uint64_t injected = 0;
  std::optional<SdoCall> call;
  for (std::size_t at = 0; at + kRecord <= size; at += kRecord) {
    const std::uint8_t* r = data + at;
    if ((r[0] & 0x27) == 0x27) {
      if (!call) call.emplace(client, r);
      continue;
    }
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
  if (call) {
    // The drive gives up the transfer: the call ends now unless a fuzzed frame ended it already.
    client.bus.inject(canopen::sdo_abort(kNode, call->index, call->sub, 0x08000000, true));
    ++injected;
  }
  // Every injected frame must be taken in by the client's I/O thread (or it hangs or lost one).
  await([&] { return client.taken() >= before + injected; }, "did not take every injected frame");
  return 0;  // and `call` joins its thread
}
