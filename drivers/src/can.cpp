#include "hil/drv/can.hpp"

#include <linux/can.h>
#include <linux/can/error.h>

#include <cstdio>

namespace hil::drv {

CanErrorInfo decode_error_frame(const CanFrame& f) {
  CanErrorInfo e;
  const std::uint32_t c = f.id;
  const std::uint8_t ctrl = f.data[1];
  e.tx_timeout = c & CAN_ERR_TX_TIMEOUT;
  e.lost_arbitration = c & CAN_ERR_LOSTARB;
  e.controller_problem = c & CAN_ERR_CRTL;
  e.protocol_violation = c & CAN_ERR_PROT;
  e.transceiver = c & CAN_ERR_TRX;
  e.no_ack = c & CAN_ERR_ACK;
  e.bus_off = c & CAN_ERR_BUSOFF;
  e.bus_error = c & CAN_ERR_BUSERROR;
  e.restarted = c & CAN_ERR_RESTARTED;
  if (e.controller_problem) {
    e.error_passive = ctrl & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE);
    e.error_warning = ctrl & (CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING);
    e.back_to_active = ctrl & CAN_ERR_CRTL_ACTIVE;
  }
  e.tx_errors = f.data[6];
  e.rx_errors = f.data[7];

  std::string& t = e.text;
  auto add = [&t](const char* s) { t += (t.empty() ? "" : ", "), t += s; };
  if (e.bus_off) add("bus-off");
  if (e.restarted) add("controller restarted");
  if (e.controller_problem) {
    std::string p = "controller problem:";
    if (ctrl & CAN_ERR_CRTL_RX_OVERFLOW) p += " rx-overflow";
    if (ctrl & CAN_ERR_CRTL_TX_OVERFLOW) p += " tx-overflow";
    if (ctrl & CAN_ERR_CRTL_RX_WARNING) p += " rx-error-warning";
    if (ctrl & CAN_ERR_CRTL_TX_WARNING) p += " tx-error-warning";
    if (ctrl & CAN_ERR_CRTL_RX_PASSIVE) p += " rx-error-passive";
    if (ctrl & CAN_ERR_CRTL_TX_PASSIVE) p += " tx-error-passive";
    if (ctrl & CAN_ERR_CRTL_ACTIVE) p += " back-to-error-active";
    if (ctrl == 0) p += " unspecified";
    add(p.c_str());
  }
  if (e.tx_timeout) add("tx timeout");
  if (e.lost_arbitration) add("lost arbitration");
  if (e.protocol_violation) add("protocol violation");
  if (e.transceiver) add("transceiver status");
  if (e.no_ack) add("no ack");
  if (e.bus_error) add("bus error");
  if (c & CAN_ERR_CNT) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "tec %u rec %u", e.tx_errors, e.rx_errors);
    add(buf);
  }
  if (t.empty()) add("error frame (no class bits)");
  return e;
}

bool BusStateTracker::update(const CanErrorInfo& e) {
  BusState next = state_;
  if (e.bus_off) {
    next = BusState::bus_off;
  } else if (e.restarted || e.back_to_active) {
    next = BusState::error_active;
  } else if (state_ != BusState::bus_off) {
    if (e.error_passive)
      next = BusState::error_passive;
    else if (e.error_warning && state_ == BusState::error_active)
      next = BusState::error_warning;
  }
  const bool changed = next != state_;
  state_ = next;
  return changed;
}

CanFrame make_error_frame(EmulatedBusError kind) {
  CanFrame f;
  f.error = true;
  f.dlc = CAN_ERR_DLC;
  switch (kind) {
    case EmulatedBusError::bus_off: f.id = CAN_ERR_BUSOFF; break;
    case EmulatedBusError::restarted: f.id = CAN_ERR_RESTARTED; break;
    case EmulatedBusError::error_passive:
      f.id = CAN_ERR_CRTL | CAN_ERR_CNT;
      f.data[1] = CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE;
      f.data[6] = 128, f.data[7] = 128;
      break;
    case EmulatedBusError::error_warning:
      f.id = CAN_ERR_CRTL | CAN_ERR_CNT;
      f.data[1] = CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING;
      f.data[6] = 97, f.data[7] = 97;
      break;
    case EmulatedBusError::back_to_active:
      f.id = CAN_ERR_CRTL;
      f.data[1] = CAN_ERR_CRTL_ACTIVE;
      break;
  }
  return f;
}

std::string to_string(const CanFrame& f) {
  char buf[64];
  int n = f.extended || f.error ? std::snprintf(buf, sizeof buf, "%08X#", f.id | (f.error ? CAN_ERR_FLAG : 0))
                                : std::snprintf(buf, sizeof buf, "%03X#", f.id);
  if (f.rtr) {
    std::snprintf(buf + n, sizeof buf - n, "R");
  } else {
    for (int i = 0; i < f.dlc && i < 8; ++i) n += std::snprintf(buf + n, sizeof buf - n, "%02X", f.data[i]);
  }
  return buf;
}

}  // namespace hil::drv
