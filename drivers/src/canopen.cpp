#include "hil/drv/canopen.hpp"

#include <cstdio>

namespace hil::drv::canopen {

std::string_view to_string(NmtState s) {
  switch (s) {
    case NmtState::boot_up: return "boot-up";
    case NmtState::stopped: return "stopped";
    case NmtState::operational: return "operational";
    case NmtState::pre_operational: return "pre-operational";
    case NmtState::unknown: break;
  }
  return "unknown";
}

CanFrame nmt(NmtCommand cmd, std::uint8_t node) {
  CanFrame f;
  f.id = kNmt;
  f.dlc = 2;
  f.data[0] = static_cast<std::uint8_t>(cmd);
  f.data[1] = node;
  return f;
}

CanFrame sync() {
  CanFrame f;
  f.id = kSync;
  return f;
}

CanFrame heartbeat(std::uint8_t node, NmtState state) {
  CanFrame f;
  f.id = kHeartbeat + node;
  f.dlc = 1;
  f.data[0] = static_cast<std::uint8_t>(state);
  return f;
}

namespace {
CanFrame sdo_frame(std::uint32_t id, std::uint8_t cs, std::uint16_t index, std::uint8_t sub) {
  CanFrame f;
  f.id = id;
  f.dlc = 8;
  f.data[0] = cs;
  put_le(&f.data[1], index, 2);
  f.data[3] = sub;
  return f;
}
}  // namespace

CanFrame sdo_download(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size) {
  // ccs=1, n = 4 - size unused bytes, e=1 expedited, s=1 size indicated.
  const std::uint8_t cs = static_cast<std::uint8_t>(0x20 | ((4 - size) << 2) | 0x03);
  CanFrame f = sdo_frame(kSdoRx + node, cs, index, sub);
  put_le(&f.data[4], value, size);
  return f;
}

CanFrame sdo_upload(std::uint8_t node, std::uint16_t index, std::uint8_t sub) {
  return sdo_frame(kSdoRx + node, 0x40, index, sub);
}

CanFrame sdo_download_ok(std::uint8_t node, std::uint16_t index, std::uint8_t sub) {
  return sdo_frame(kSdoTx + node, 0x60, index, sub);
}

CanFrame sdo_upload_ok(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size) {
  const std::uint8_t cs = static_cast<std::uint8_t>(0x40 | ((4 - size) << 2) | 0x03);
  CanFrame f = sdo_frame(kSdoTx + node, cs, index, sub);
  put_le(&f.data[4], value, size);
  return f;
}

CanFrame sdo_abort(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint32_t code, bool from_server) {
  CanFrame f = sdo_frame((from_server ? kSdoTx : kSdoRx) + node, 0x80, index, sub);
  put_le(&f.data[4], code, 4);
  return f;
}

SdoReply parse_sdo_reply(const CanFrame& f) {
  SdoReply r;
  if (f.dlc < 8 || f.rtr) return r;  // malformed
  r.index = static_cast<std::uint16_t>(get_le(&f.data[1], 2));
  r.sub = f.data[3];
  const std::uint8_t cs = f.data[0];
  switch (cs >> 5) {
    case 2:                // upload response
      if (!(cs & 0x02)) {  // not expedited: the server starts a segmented transfer
        r.kind = SdoReply::Kind::unsupported;
        return r;
      }
      r.kind = SdoReply::Kind::upload;
      r.size = (cs & 0x01) ? static_cast<std::uint8_t>(4 - ((cs >> 2) & 0x03)) : 4;
      r.value = get_le(&f.data[4], r.size);
      return r;
    case 3: r.kind = SdoReply::Kind::download; return r;
    case 4:
      r.kind = SdoReply::Kind::abort;
      r.value = get_le(&f.data[4], 4);
      return r;
    default: r.kind = SdoReply::Kind::unsupported; return r;
  }
}

std::string_view sdo_abort_name(std::uint32_t code) {
  switch (code) {
    case 0x05030000: return "toggle bit not alternated";
    case 0x05040000: return "SDO protocol timed out";
    case 0x05040001: return "client/server command specifier not valid or unknown";
    case 0x05040002: return "invalid block size";
    case 0x05040003: return "invalid sequence number";
    case 0x05040004: return "CRC error";
    case 0x05040005: return "out of memory";
    case 0x06010000: return "unsupported access to an object";
    case 0x06010001: return "attempt to read a write only object";
    case 0x06010002: return "attempt to write a read only object";
    case 0x06020000: return "object does not exist in the object dictionary";
    case 0x06040041: return "object cannot be mapped to the PDO";
    case 0x06040042: return "the number and length of the objects to be mapped would exceed PDO length";
    case 0x06040043: return "general parameter incompatibility";
    case 0x06040047: return "general internal incompatibility in the device";
    case 0x06060000: return "access failed due to a hardware error";
    case 0x06070010: return "data type does not match, length of service parameter does not match";
    case 0x06070012: return "data type does not match, length of service parameter too high";
    case 0x06070013: return "data type does not match, length of service parameter too low";
    case 0x06090011: return "sub-index does not exist";
    case 0x06090030: return "invalid value for parameter";
    case 0x06090031: return "value of parameter written too high";
    case 0x06090032: return "value of parameter written too low";
    case 0x06090036: return "maximum value is less than minimum value";
    case 0x060A0023: return "resource not available: SDO connection";
    case 0x08000000: return "general error";
    case 0x08000020: return "data cannot be transferred or stored to the application";
    case 0x08000021: return "data cannot be transferred or stored to the application because of local control";
    case 0x08000022: return "data cannot be transferred or stored to the application because of the present device state";
    case 0x08000023: return "object dictionary dynamic generation fails or no object dictionary is present";
    case 0x08000024: return "no data available";
    default: return "unknown abort code";
  }
}

std::string object_name(std::uint16_t index, std::uint8_t sub) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%04X:%02X", index, sub);
  return buf;
}

std::optional<Emcy> parse_emcy(const CanFrame& f) {
  if (f.dlc != 8 || f.rtr) return std::nullopt;
  Emcy e;
  e.error_code = static_cast<std::uint16_t>(get_le(&f.data[0], 2));
  e.error_register = f.data[2];
  for (int i = 0; i < 5; ++i) e.manufacturer[i] = f.data[3 + i];
  return e;
}

CanFrame emcy(std::uint8_t node, const Emcy& e) {
  CanFrame f;
  f.id = kEmcy + node;
  f.dlc = 8;
  put_le(&f.data[0], e.error_code, 2);
  f.data[2] = e.error_register;
  for (int i = 0; i < 5; ++i) f.data[3 + i] = e.manufacturer[i];
  return f;
}

std::string_view emcy_class_name(std::uint16_t c) {
  // CiA 301's emergency error codes, with CiA 402's (IEC 61800-7-201) drive codes: specific
  // codes first, then the classes.
  switch (c) {
    case 0x2220: return "continuous over current inside the device";
    case 0x2310: return "continuous over current, device output side";
    case 0x3210: return "DC link over-voltage";
    case 0x3220: return "DC link under-voltage";
    case 0x4210: return "excess temperature, device";
    case 0x4310: return "excess temperature, drive";
    case 0x6010: return "software reset (watchdog)";
    case 0x6320: return "parameter error";
    case 0x7121: return "motor blocked";
    case 0x7300: return "sensor";
    case 0x7305: return "incremental sensor 1 fault";
    case 0x7310: return "speed sensor";
    case 0x7320: return "position sensor";
    case 0x8110: return "CAN overrun (objects lost)";
    case 0x8120: return "CAN in error passive mode";
    case 0x8130: return "life guard or heartbeat error: the drive lost a heartbeat it consumes (0x1016) or life guarding";
    case 0x8140: return "recovered from bus-off";
    case 0x8150: return "CAN-ID collision";
    case 0x8210: return "PDO not processed due to length error";
    case 0x8220: return "PDO length exceeded";
    case 0x8240: return "unexpected SYNC data length";
    case 0x8250: return "RPDO timeout";
    case 0x8311: return "excess torque";
    case 0x8611: return "following error";
    case 0x8612: return "reference limit";
    default: break;
  }
  switch (c >> 8) {
    case 0x00: return "error reset or no error";
    case 0x10: return "generic error";
    case 0x20: return "current";
    case 0x21: return "current, device input side";
    case 0x22: return "current inside the device";
    case 0x23: return "current, device output side";
    case 0x30: return "voltage";
    case 0x31: return "mains voltage";
    case 0x32: return "voltage inside the device";
    case 0x33: return "output voltage";
    case 0x40: return "temperature";
    case 0x41: return "ambient temperature";
    case 0x42: return "device temperature";
    case 0x50: return "device hardware";
    case 0x60: return "device software";
    case 0x61: return "internal software";
    case 0x62: return "user software";
    case 0x63: return "data set";
    case 0x70: return "additional modules";
    case 0x80: return "monitoring";
    case 0x81: return "communication";
    case 0x82: return "protocol error";
    case 0x86: return "positioning controller";
    case 0x90: return "external error";
    case 0xF0: return "additional functions";
    case 0xFF: return "device specific";
    default: break;
  }
  switch (c >> 12) {
    case 0x2: return "current";
    case 0x3: return "voltage";
    case 0x4: return "temperature";
    case 0x5: return "device hardware";
    case 0x6: return "device software";
    case 0x7: return "additional modules";
    case 0x8: return "monitoring";
    default: return "unknown error class";
  }
}

std::string describe(const Emcy& e) {
  static constexpr const char* kBits[8] = {"generic",       "current",        "voltage",  "temperature",
                                           "communication", "device profile", "reserved", "manufacturer"};
  std::string reg;
  for (int b = 0; b < 8; ++b) {
    if (e.error_register & (1u << b)) reg += (reg.empty() ? "" : ", ") + std::string(kBits[b]);
  }
  char buf[240];
  std::snprintf(buf, sizeof buf, "EMCY 0x%04X (%.*s), register 0x%02X (%s), manufacturer %02X %02X %02X %02X %02X", e.error_code,
                static_cast<int>(emcy_class_name(e.error_code).size()), emcy_class_name(e.error_code).data(), e.error_register,
                reg.empty() ? "none" : reg.c_str(), e.manufacturer[0], e.manufacturer[1], e.manufacturer[2], e.manufacturer[3],
                e.manufacturer[4]);
  return buf;
}

}  // namespace hil::drv::canopen

namespace hil::drv::cia402 {

std::string_view to_string(State s) {
  switch (s) {
    case State::not_ready_to_switch_on: return "not ready to switch on";
    case State::switch_on_disabled: return "switch on disabled";
    case State::ready_to_switch_on: return "ready to switch on";
    case State::switched_on: return "switched on";
    case State::operation_enabled: return "operation enabled";
    case State::quick_stop_active: return "quick stop active";
    case State::fault_reaction_active: return "fault reaction active";
    case State::fault: return "fault";
  }
  return "?";
}

State decode_statusword(std::uint16_t sw) {
  if ((sw & 0x4F) == 0x08) return State::fault;
  if ((sw & 0x4F) == 0x0F) return State::fault_reaction_active;
  if ((sw & 0x4F) == 0x40) return State::switch_on_disabled;
  switch (sw & 0x6F) {
    case 0x21: return State::ready_to_switch_on;
    case 0x23: return State::switched_on;
    case 0x27: return State::operation_enabled;
    case 0x07: return State::quick_stop_active;
    default: return State::not_ready_to_switch_on;
  }
}

std::uint16_t next_controlword(State state, Target target, bool reset) {
  switch (state) {
    case State::fault: return reset ? kCwFaultReset : kCwDisableVoltage;
    case State::fault_reaction_active:
    case State::not_ready_to_switch_on: return kCwDisableVoltage;
    case State::quick_stop_active: return target == Target::quick_stop ? kCwQuickStop : kCwDisableVoltage;
    case State::switch_on_disabled:
      return target == Target::disabled || target == Target::quick_stop ? kCwDisableVoltage : kCwShutdown;
    case State::ready_to_switch_on:
      return target == Target::disabled || target == Target::quick_stop ? kCwDisableVoltage : kCwSwitchOn;
    case State::switched_on:
    case State::operation_enabled:
      if (target == Target::quick_stop) return state == State::operation_enabled ? kCwQuickStop : kCwDisableVoltage;
      return target == Target::operation_enabled ? kCwEnableOperation
             : target == Target::switched_on     ? kCwSwitchOn
                                                 : kCwDisableVoltage;
  }
  return kCwDisableVoltage;
}

}  // namespace hil::drv::cia402
