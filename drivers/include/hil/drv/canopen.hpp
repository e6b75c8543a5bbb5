// CANopen (CiA 301) and CiA 402 encoding: COB-IDs, NMT, SYNC, expedited SDO, EMCY, the drive
// state machine's statusword/controlword. Pure functions, shared by the client and the emulator.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "hil/drv/can.hpp"

namespace hil::drv::canopen {

// Predefined connection set (CiA 301 7.3.5).
inline constexpr std::uint32_t kNmt = 0x000;
inline constexpr std::uint32_t kSync = 0x080;
inline constexpr std::uint32_t kEmcy = 0x080;                 // + node
inline constexpr std::uint32_t kTpdo1 = 0x180;                // + node; TPDO2..4: +0x100 each
inline constexpr std::uint32_t kRpdo1 = 0x200;                // + node; RPDO2..4: +0x100 each
inline constexpr std::uint32_t kSdoTx = 0x580;                // server -> client, + node
inline constexpr std::uint32_t kSdoRx = 0x600;                // client -> server, + node
inline constexpr std::uint32_t kHeartbeat = 0x700;            // + node
inline constexpr std::uint32_t kCobIdInvalid = 0x80000000u;   // PDO COB-ID bit 31: PDO does not exist
inline constexpr std::uint32_t kCobIdExtended = 0x20000000u;  // COB-ID bit 29: a 29-bit CAN id

// CiA 301 (7.3.5, restricted CAN-IDs): ids no configurable object (a PDO, the SYNC, EMCY) may
// use, because NMT, the default SDO channels and NMT error control own them, or they are
// reserved: 0x000, 0x001-0x07F, 0x101-0x180, 0x581-0x5FF, 0x601-0x67F, 0x6E0-0x6FF, 0x701-0x7FF.
constexpr bool restricted_can_id(std::uint32_t id11) noexcept {
  return id11 <= 0x07F || (id11 >= 0x101 && id11 <= 0x180) || (id11 >= 0x581 && id11 <= 0x5FF) ||
         (id11 >= 0x601 && id11 <= 0x67F) || (id11 >= 0x6E0 && id11 <= 0x6FF) || id11 >= 0x701;
}

enum class NmtCommand : std::uint8_t {
  start = 0x01,
  stop = 0x02,
  enter_pre_operational = 0x80,
  reset_node = 0x81,
  reset_communication = 0x82,
};

// Heartbeat state byte.
enum class NmtState : std::uint8_t {
  boot_up = 0x00,
  stopped = 0x04,
  operational = 0x05,
  pre_operational = 0x7F,
  unknown = 0xFF,
};
std::string_view to_string(NmtState s);

CanFrame nmt(NmtCommand cmd, std::uint8_t node);  // node 0 = all nodes
CanFrame sync();
CanFrame heartbeat(std::uint8_t node, NmtState state);

// Expedited SDO (at most 4 data bytes). Command specifiers: download request 0x23/0x27/0x2B/0x2F
// (4/3/2/1 bytes), download response 0x60, upload request 0x40, upload response 0x43/0x47/0x4B/0x4F,
// abort 0x80.
CanFrame sdo_download(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size);
CanFrame sdo_upload(std::uint8_t node, std::uint16_t index, std::uint8_t sub);
CanFrame sdo_download_ok(std::uint8_t node, std::uint16_t index, std::uint8_t sub);
CanFrame sdo_upload_ok(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size);
// `from_server`: on 0x580+node, else on 0x600+node.
CanFrame sdo_abort(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint32_t code, bool from_server);

struct SdoReply {
  enum class Kind { upload, download, abort, unsupported, malformed } kind = Kind::malformed;
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::uint32_t value = 0;  // upload data, or the abort code
  std::uint8_t size = 0;    // upload data bytes (0 when the server did not say)
};
// Parses a server reply (0x580+node). A frame shorter than 8 bytes is malformed.
SdoReply parse_sdo_reply(const CanFrame& f);

// The CiA 301 name of an SDO abort code, e.g. 0x06020000 -> "object does not exist in the object dictionary".
std::string_view sdo_abort_name(std::uint32_t code);
// "0x6060:00"
std::string object_name(std::uint16_t index, std::uint8_t sub);

struct Emcy {
  std::uint16_t error_code = 0;
  std::uint8_t error_register = 0;
  std::array<std::uint8_t, 5> manufacturer{};
};
// An EMCY frame must carry 8 bytes; anything shorter is malformed (nullopt).
std::optional<Emcy> parse_emcy(const CanFrame& f);
CanFrame emcy(std::uint8_t node, const Emcy& e);
// The error-code class from CiA 301 table 21 / CiA 402, e.g. 0x2310 -> "current, device output side".
std::string_view emcy_class_name(std::uint16_t code);
// "EMCY 0x2310 (current, device output side), register 0x03 (current, generic), manufacturer 01 02 03 04 05"
std::string describe(const Emcy& e);

// Little-endian helpers for PDO and SDO payloads.
inline std::uint32_t get_le(const std::uint8_t* p, int bytes) {
  std::uint32_t v = 0;
  for (int i = bytes - 1; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}
inline void put_le(std::uint8_t* p, std::uint32_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}

}  // namespace hil::drv::canopen

namespace hil::drv::cia402 {

// Objects used (CiA 402-2).
inline constexpr std::uint16_t kErrorCode = 0x603F;
inline constexpr std::uint16_t kControlword = 0x6040;
inline constexpr std::uint16_t kStatusword = 0x6041;
inline constexpr std::uint16_t kModesOfOperation = 0x6060;
inline constexpr std::uint16_t kModesDisplay = 0x6061;
inline constexpr std::uint16_t kPositionActual = 0x6064;
inline constexpr std::uint16_t kVelocityActual = 0x606C;
inline constexpr std::uint16_t kTargetPosition = 0x607A;
inline constexpr std::uint16_t kInterpolationPeriod = 0x60C2;
inline constexpr std::uint16_t kQuickStopOption = 0x605A;
inline constexpr std::uint16_t kAbortConnectionOption = 0x6007;  // i16: 0 none, 1 fault, 2 disable voltage, 3 quick stop
inline constexpr std::uint16_t kFollowingErrorWindow = 0x6065;   // u32, position units; 0xFFFFFFFF: off
inline constexpr std::uint16_t kFollowingErrorTimeout = 0x6066;  // u16, ms
inline constexpr std::uint16_t kMaxProfileVelocity = 0x607F;     // u32, velocity units
inline constexpr std::uint16_t kQuickStopDeceleration = 0x6085;  // u32, acceleration units
inline constexpr std::uint16_t kSupportedDriveModes = 0x6502;    // u32, bit 7: csp
inline constexpr std::int8_t kModeCsp = 8;                       // cyclic synchronous position

// Controlword commands (bits 0 switch on, 1 enable voltage, 2 quick stop, 3 enable operation, 7 fault reset).
inline constexpr std::uint16_t kCwDisableVoltage = 0x0000;
inline constexpr std::uint16_t kCwQuickStop = 0x0002;
inline constexpr std::uint16_t kCwShutdown = 0x0006;
inline constexpr std::uint16_t kCwSwitchOn = 0x0007;  // also "disable operation" from operation enabled
inline constexpr std::uint16_t kCwEnableOperation = 0x000F;
inline constexpr std::uint16_t kCwFaultReset = 0x0080;

enum class State : std::uint8_t {
  not_ready_to_switch_on,
  switch_on_disabled,
  ready_to_switch_on,
  switched_on,
  operation_enabled,
  quick_stop_active,
  fault_reaction_active,
  fault,
};
std::string_view to_string(State s);

// Statusword -> state, by the masks of CiA 402 table 30.
State decode_statusword(std::uint16_t sw);

// What the client wants the drive to be.
enum class Target : std::uint8_t { disabled, switched_on, operation_enabled, quick_stop };

// The controlword that moves a drive from `state` one step toward `target`. In fault it returns
// kCwFaultReset when `reset` is set (the caller makes the 0 -> 1 edge), else 0. Target
// quick_stop: quick stop from operation enabled, held while the drive ramps down.
std::uint16_t next_controlword(State state, Target target, bool reset);

}  // namespace hil::drv::cia402
