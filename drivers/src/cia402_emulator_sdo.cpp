// The CiA 402 drive emulator's object dictionary and SDO server (expedited transfers, with the
// checks CiA 301 and 402 ask of a write: PDO mapping, COB-IDs, consumer heartbeat entries, modes).
#include "cia402_emulator_impl.hpp"

namespace hil::drv {

void Cia402DriveEmulator::Impl::reset_communication() {
  def(0x1000, 0, 0x00020192, 4, false);  // CiA 402, servo drive
  def(0x1001, 0, 0, 1, false);
  def(0x1006, 0, 0, 4, true);  // communication cycle period, us
  for (int k = 0; k <= kConsumerEntries; ++k) od.erase(key(0x1016, static_cast<std::uint8_t>(k)));
  od.erase(key(0x1017, 0)), od.erase(key(0x100C, 0)), od.erase(key(0x100D, 0));
  if (cfg.node_guarding) {
    def(0x100C, 0, 0, 2, true);  // guard time, ms
    def(0x100D, 0, 0, 1, true);  // life time factor
  } else {
    def(0x1017, 0, 0, 2, true);
  }
  guard_toggle = false;
  guarded = false;
  if (cfg.heartbeat_consumer && !cfg.node_guarding) {
    def(0x1016, 0, kConsumerEntries, 1, false);
    for (int k = 1; k <= kConsumerEntries; ++k) def(0x1016, static_cast<std::uint8_t>(k), 0, 4, true);
  }
  consumer_started = {};
  def(0x1018, 0, 4, 1, false);
  def(0x1018, 1, 0x00000ABC, 4, false);  // vendor (made up)
  def(0x1018, 2, 0x00000402, 4, false);
  def(0x1018, 3, 1, 4, false);
  def(0x1018, 4, 1, 4, false);
  for (int i = 0; i < 4; ++i) {  // a drive with fewer PDOs does not have the others at all
    for (std::uint16_t base : {0x1400, 0x1600, 0x1800, 0x1A00}) {
      for (std::uint8_t s = 0; s <= 8; ++s) od.erase(key(static_cast<std::uint16_t>(base + i), s));
    }
  }
  for (std::uint16_t k = 0; k < static_cast<std::uint16_t>(cfg.pdos); ++k) {
    def(0x1400 + k, 0, 2, 1, false);
    const bool own = cfg.own_pdo_ids && k > 0;
    def(0x1400 + k, 1, own ? 0x500u + 0x20u * k + n : kRpdo1 + 0x100u * k + n, 4, true);
    def(0x1400 + k, 2, 0xFF, 1, true);
    def(0x1800 + k, 0, 2, 1, false);
    def(0x1800 + k, 1, own ? 0x40000000u | (0x480u + 0x20u * k + n) : kTpdo1 + 0x100u * k + n, 4, true);
    def(0x1800 + k, 2, 0xFF, 1, true);
    def(0x1600 + k, 0, k == 0 ? 1 : 0, 1, true);
    def(0x1A00 + k, 0, k == 0 ? 1 : 0, 1, true);
    for (std::uint8_t s = 1; s <= 8; ++s) {
      def(0x1600 + k, s, k == 0 && s == 1 ? 0x60400010 : 0, 4, true);
      def(0x1A00 + k, s, k == 0 && s == 1 ? 0x60410010 : 0, 4, true);
    }
  }
  rpdo_pending = {};
  tpdo_count = {};
}

void Cia402DriveEmulator::Impl::reset_application() {
  def(cia402::kErrorCode, 0, 0, 2, false, true);
  def(cia402::kControlword, 0, 0, 2, true, true);
  def(cia402::kStatusword, 0, 0, 2, false, true);
  def(cia402::kModesOfOperation, 0, 0, 1, true, true);
  def(cia402::kModesDisplay, 0, 0, 1, false, true);
  def(cia402::kPositionActual, 0, 0, 4, false, true);
  def(cia402::kVelocityActual, 0, 0, 4, false, true);
  def(cia402::kTargetPosition, 0, 0, 4, true, true);
  def(cia402::kSupportedDriveModes, 0, 0x00000081, 4, false);  // profile position, cyclic synchronous position
  if (cfg.interpolation_period) {
    def(cia402::kInterpolationPeriod, 0, 2, 1, false);
    def(cia402::kInterpolationPeriod, 1, 1, 1, true);
    def(cia402::kInterpolationPeriod, 2, static_cast<std::uint8_t>(-3), 1, true);
  }
  if (cfg.following_error) {
    def(cia402::kFollowingErrorWindow, 0, 0xFFFFFFFF, 4, true);
    def(cia402::kFollowingErrorTimeout, 0, 10, 2, true);
  }
  def(cia402::kQuickStopOption, 0, cfg.quick_stop_ramp ? 2 : 0, 2, false);
  if (cfg.abort_connection_option) def(cia402::kAbortConnectionOption, 0, 1, 2, true);
  if (cfg.quick_stop_ramp) def(cia402::kQuickStopDeceleration, 0, 0x7FFFFFFF, 4, true);
  mode_written = {};
  following_out = false;
  state = State::not_ready_to_switch_on;
  last_cw = 0;
  app_step();
}

std::uint32_t Cia402DriveEmulator::Impl::check_write(std::uint16_t index, std::uint8_t sub, std::uint32_t v) {
  const auto pdo_valid = [&](std::uint16_t comm) { return !(get(comm, 1) & kCobIdInvalid); };
  const bool rpdo_map = index >= 0x1600 && index <= 0x1603, tpdo_map = index >= 0x1A00 && index <= 0x1A03;
  if (rpdo_map || tpdo_map) {
    const std::uint16_t comm = static_cast<std::uint16_t>(rpdo_map ? index - 0x200 : index - 0x200);
    if (pdo_valid(comm)) return kAbortState;
    // An entry (index << 16 | sub << 8 | bits) must name an object this PDO can carry, whole.
    const auto entry_mappable = [&](std::uint32_t entry) {
      const auto it = od.find(entry >> 8);
      return it != od.end() && it->second.mappable && (entry & 0xFF) == it->second.size * 8u &&
             (!rpdo_map || it->second.writable);
    };
    if (sub == 0) {
      // CiA 301: the count is checked when written, against the entries it counts (an entry
      // left at 0 maps nothing: taken, the next PDO would look up an object that is not there).
      if (v > 8) return kAbortPdoLength;
      int bits = 0;
      for (std::uint8_t s = 1; s <= v; ++s) {
        const std::uint32_t entry = get(index, s);
        if (!entry_mappable(entry)) return kAbortNotMappable;
        bits += entry & 0xFF;
      }
      return bits > 64 ? kAbortPdoLength : 0;
    }
    if (get(index, 0) != 0) return kAbortState;  // CiA 301: clear the count before remapping
    return entry_mappable(v) ? 0 : kAbortNotMappable;
  }
  if ((index >= 0x1400 && index <= 0x1403) || (index >= 0x1800 && index <= 0x1803)) {
    if (sub == 1 && !(v & kCobIdInvalid) && pdo_valid(index) && (v & 0x7FF) != (get(index, 1) & 0x7FF)) {
      return kAbortValue;  // change the COB-ID of a valid PDO: invalidate it first
    }
    // A PDO on a restricted id would speak as NMT, SDO or a heartbeat to every node (a TPDO on
    // 0x000 is an NMT command); 29-bit ids this drive does not have.
    if (sub == 1 && !(v & kCobIdInvalid) && ((v & kCobIdExtended) || restricted_can_id(v & 0x7FF))) return kAbortValue;
    return 0;
  }
  if (index == 0x1016 && sub >= 1) {
    // CiA 301: one entry per node; a second with a time for a node already watched is refused.
    if ((v & 0xFFFF) == 0 || ((v >> 16) & 0xFF) == 0) return 0;
    for (int k = 1; k <= kConsumerEntries; ++k) {
      const std::uint32_t e = get(0x1016, static_cast<std::uint8_t>(k));
      if (k != sub && (e & 0xFFFF) != 0 && ((e >> 16) & 0xFF) == ((v >> 16) & 0xFF)) return kAbortIncompatible;
    }
    return 0;
  }
  if (index == cia402::kAbortConnectionOption) {
    const auto o = static_cast<std::int16_t>(v);
    return o <= 3 ? 0 : kAbortValue;  // 0..3, or manufacturer-specific (negative)
  }
  if (index == cia402::kModesOfOperation) {
    const auto m = static_cast<std::int8_t>(v);
    return m == cia402::kModeCsp || m == 0 ? 0 : kAbortValue;
  }
  return 0;
}

void Cia402DriveEmulator::Impl::on_sdo(const CanFrame& f) {
  if (f.dlc < 8) return;  // not an SDO request: ignore, as drives do
  const std::uint8_t cs = f.data[0];
  const auto index = static_cast<std::uint16_t>(get_le(&f.data[1], 2));
  const std::uint8_t sub = f.data[3];
  const auto abort = [&](std::uint32_t code) { send_late(sdo_abort(n, index, sub, code, true)); };
  if ((cs >> 5) == 4) return;  // the client aborted: nothing to clean up for expedited transfers
  if (auto fail = sdo_failures.find(key(index, sub)); fail != sdo_failures.end()) return abort(fail->second);
  const auto it = od.find(key(index, sub));
  if (it == od.end()) {
    const bool index_exists = od.lower_bound(key(index, 0)) != od.end() && (od.lower_bound(key(index, 0))->first >> 8) == index;
    return abort(index_exists ? kAbortNoSub : kAbortNoObject);
  }
  Obj& o = it->second;
  if (index == cia402::kModesDisplay) update_mode_display();
  if (cs == 0x40) return send_late(sdo_upload_ok(n, index, sub, o.value, o.size));
  if ((cs >> 5) != 1) return abort(kAbortCommand);
  if (!(cs & 0x02)) return abort(kAbortCommand);  // segmented download: not supported here
  if (!o.writable) return abort(kAbortReadOnly);
  const int size = (cs & 0x01) ? 4 - ((cs >> 2) & 0x03) : o.size;
  if (size != o.size) return abort(kAbortLength);
  const std::uint32_t v = get_le(&f.data[4], size);
  if (const std::uint32_t code = check_write(index, sub, v)) return abort(code);
  if (index == cia402::kModesOfOperation && v != o.value) mode_written = Clock::now();
  o.value = v;
  if (index == 0x1017) arm_heartbeat();
  if (index == 0x1016 && sub >= 1) consumer_started[static_cast<std::size_t>(sub - 1)] = false;  // from its next heartbeat
  if (index == cia402::kControlword || index == cia402::kModesOfOperation || index == cia402::kTargetPosition) app_step();
  send_late(sdo_download_ok(n, index, sub));
}

}  // namespace hil::drv
