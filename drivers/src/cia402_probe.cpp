#include "hil/drv/cia402_probe.hpp"

#include <cmath>
#include <cstdio>
#include <numbers>

namespace hil::drv {

namespace {
std::string hex(std::uint32_t v, int digits) {
  char b[16];
  std::snprintf(b, sizeof b, "0x%0*X", digits, v);
  return b;
}
}  // namespace

const Cia402Probe::Object* Cia402Probe::find(std::uint16_t index, std::uint8_t sub) const {
  for (const auto& o : objects) {
    if (o.index == index && o.sub == sub) return &o;
  }
  return nullptr;
}

Cia402Probe probe(Cia402Drive& client) { return probe(client.sdo(), client.config()); }

Cia402Probe probe(SdoClient& sdo, const Cia402Config& cfg) {
  Cia402Probe p;
  p.device_type = sdo.read(0x1000, 0);  // no answer, or an abort: not a drive we can talk to
  if ((p.device_type & 0xFFFF) != 402) {
    throw DriveError("CiA 402 drive node " + std::to_string(cfg.node_id) + " on " + cfg.interface +
                     ": not a CiA 402 device (0x1000:00 device type = " + hex(p.device_type, 8) + ")");
  }
  // A drive that does not answer one object (no abort: a timeout, or a segmented reply) is
  // reported for it, and the probe goes on: one object's error does not end the
  // whole probe. Three in a row mean the drive stopped answering: that does end it.
  int unanswered_in_a_row = 0;
  const auto read = [&](std::uint16_t index, std::uint8_t sub, const std::string& name, bool required) -> Cia402Probe::Object& {
    Cia402Probe::Object o{index, sub, name, required, std::nullopt, 0, {}};
    try {
      o.value = sdo.read(index, sub);
      unanswered_in_a_row = 0;
    } catch (const SdoAbortError& e) {
      o.abort_code = e.code;
      unanswered_in_a_row = 0;
    } catch (const DriveError& e) {
      if (++unanswered_in_a_row >= 3) throw;
      o.no_answer = e.what();
    }
    p.objects.push_back(o);
    return p.objects.back();
  };
  read(0x1018, 1, "vendor id", false);
  read(0x1018, 2, "product code", false);
  read(0x1018, 3, "revision number", false);
  read(0x1018, 4, "serial number", false);
  const auto modes = read(cia402::kSupportedDriveModes, 0, "supported drive modes", false).value;
  // The drive's heartbeat, or node guarding in its place (CiA 301 allows either).
  const bool heartbeat = read(0x1017, 0, "producer heartbeat time", false).value.has_value();
  bool guarding = false;
  if (!heartbeat) {
    const bool guard_time = read(0x100C, 0, "guard time", false).value.has_value();
    guarding = read(0x100D, 0, "life time factor", false).value.has_value() && guard_time;
  }
  // How the drive watches the bench: its consumer heartbeat time (or, with node guarding, its life
  // guarding) and what it does when the bench stops (0x6007).
  const bool watch_required = cfg.bench_heartbeat.required;
  const bool consumer = heartbeat && read(0x1016, 0, "consumer heartbeat time entries", watch_required).value.has_value();
  const bool abort_option =
      read(cia402::kAbortConnectionOption, 0, "abort connection option code", watch_required).value.has_value();
  for (std::uint16_t k = 0; k < 4; ++k) {
    p.rpdos +=
        read(static_cast<std::uint16_t>(0x1400 + k), 1, "RPDO" + std::to_string(k + 1) + " COB-ID", k == 0).value.has_value();
    if (k == 0) read(0x1600, 0, "RPDO1 mapping count", true);
  }
  for (std::uint16_t k = 0; k < 4; ++k) {
    p.tpdos +=
        read(static_cast<std::uint16_t>(0x1800 + k), 1, "TPDO" + std::to_string(k + 1) + " COB-ID", k == 0).value.has_value();
    if (k == 0) read(0x1A00, 0, "TPDO1 mapping count", true);
  }
  read(cia402::kControlword, 0, "controlword", true);
  read(cia402::kStatusword, 0, "statusword", true);
  read(cia402::kModesOfOperation, 0, "modes of operation", true);
  read(cia402::kModesDisplay, 0, "modes of operation display", true);
  read(cia402::kPositionActual, 0, "position actual value", true);
  read(cia402::kTargetPosition, 0, "target position", true);
  read(cia402::kErrorCode, 0, "error code", false);
  const bool ip = read(cia402::kInterpolationPeriod, 1, "interpolation time period value", false).value.has_value();
  const auto window = read(cia402::kFollowingErrorWindow, 0, "following error window", false).value;
  const auto timeout = read(cia402::kFollowingErrorTimeout, 0, "following error timeout", false).value;
  const bool vmax = read(cia402::kMaxProfileVelocity, 0, "max profile velocity", false).value.has_value();
  const auto qs_option = read(cia402::kQuickStopOption, 0, "quick stop option code", false).value;
  const bool qs_dec = read(cia402::kQuickStopDeceleration, 0, "quick stop deceleration", false).value.has_value();
  const bool cycle = read(0x1006, 0, "communication cycle period", false).value.has_value();

  for (const auto& o : p.objects) {
    if (o.required && !o.value) {
      p.usable = false;
      p.lacks.push_back(hex(o.index, 4) + ":" + hex(o.sub, 2).substr(2) + " " + o.name + " (required: configure() will fail)");
    }
  }
  if (!heartbeat && !guarding) {
    p.usable = false;
    p.lacks.push_back(
        "0x1017 producer heartbeat time, and node guarding 0x100C/0x100D in its place (required, one of them: nothing would "
        "tell that the drive stopped answering)");
  }
  p.csp_supported = !modes || (*modes & 0x80);
  if (!p.csp_supported) {
    p.usable = false;
    p.lacks.push_back("cyclic synchronous position mode (0x6502 = " + hex(*modes, 8) + ", bit 7 clear)");
  }
  const double deg_per_count = std::abs(cfg.units.rad_per_count()) * 180 / std::numbers::pi;
  char line[256];
  const auto& bw = cfg.bench_heartbeat;
  if (heartbeat) {
    std::snprintf(line, sizeof line, "0x1017 = %lld ms: its heartbeat, lost after %lld ms",
                  static_cast<long long>(cfg.heartbeat_producer.count()), static_cast<long long>(cfg.heartbeat_timeout.count()));
    p.plan.push_back(line);
  } else if (guarding) {
    const auto& g = cfg.node_guarding;
    std::snprintf(line, sizeof line,
                  "node guarding in place of the heartbeat it lacks: 0x100C = %lld ms, 0x100D = %d, a request every %lld ms "
                  "(replies lost after %lld ms); its life guarding watches the bench for %lld ms",
                  static_cast<long long>(g.guard_time.count()), g.life_time_factor, static_cast<long long>(g.guard_time.count()),
                  static_cast<long long>(cfg.heartbeat_timeout.count()),
                  static_cast<long long>(g.guard_time.count()) * g.life_time_factor);
    p.plan.push_back(line);
  }
  if (consumer) {
    std::snprintf(line, sizeof line, "0x1016: watch the bench's heartbeat (node %u, every %lld ms) for %lld ms", bw.node_id,
                  static_cast<long long>(bw.producer.count()), static_cast<long long>(bw.drive_timeout.count()));
    p.plan.push_back(line);
  } else if (heartbeat && !watch_required) {
    p.lacks.push_back(
        "0x1016 consumer heartbeat time (the drive cannot tell that the bench died; bench_heartbeat.required: false)");
  }
  if (abort_option) {
    p.plan.push_back(std::string("0x6007 = ") + std::to_string(bw.on_loss) +
                     (bw.on_loss == 3   ? " (quick stop)"
                      : bw.on_loss == 2 ? " (disable voltage)"
                                        : " (fault)") +
                     " when the bench stops");
  } else if (!watch_required) {
    p.lacks.push_back("0x6007 abort connection option code (what the drive does when the bench stops is its maker's choice)");
  }
  p.plan.push_back(
      "map RPDO1 = controlword 0x6040 + target position 0x607A, TPDO1 = statusword 0x6041 + position actual "
      "0x6064, both on every SYNC");
  if (cfg.disable_unused_pdos) {
    std::snprintf(line, sizeof line, "invalidate the other PDOs it has (%d RPDO, %d TPDO of 4 each): bit 31 of their own COB-IDs",
                  p.rpdos - 1, p.tpdos - 1);
    p.plan.push_back(line);
  }
  p.plan.push_back("0x6060 = 8 (cyclic synchronous position), then poll 0x6061 for up to " +
                   std::to_string(cfg.transition_timeout.count()) + " ms");
  if (ip) {
    p.plan.push_back("0x60C2 interpolation period = the SYNC period");
  } else {
    p.lacks.push_back("0x60C2 interpolation time period (optional: the drive takes its period from SYNC)");
  }
  const auto& lim = cfg.limits;
  if (window) {
    if (*window == 0xFFFFFFFF) {
      p.plan.push_back("following error window 0x6065 is off (0xFFFFFFFF) in the drive");
    } else {
      std::snprintf(line, sizeof line, "following error window 0x6065 in the drive: %u counts = %.4g deg, timeout 0x6066: %s ms",
                    *window, *window * deg_per_count, timeout ? std::to_string(*timeout).c_str() : "?");
      p.plan.push_back(line);
    }
    if (lim.following_error_window_rad > 0) {
      std::snprintf(line, sizeof line, "write following error window 0x6065 = %.4g deg (from the drive file)",
                    lim.following_error_window_rad * 180 / std::numbers::pi);
      p.plan.push_back(line);
    }
    // The window in effect against what the bench's targets make of the drive's lag.
    const double rpc = std::abs(cfg.units.rad_per_count());
    const double in_effect = lim.following_error_window_rad > 0 ? std::nearbyint(lim.following_error_window_rad / rpc) * rpc
                             : *window != 0xFFFFFFFF            ? *window * rpc
                                                                : 0.0;
    if (const std::string problem = following_window_problem(cfg, in_effect); !problem.empty()) {
      p.usable = false;
      p.refused.push_back(problem);
    }
  } else {
    p.lacks.push_back("0x6065/0x6066 following error window and timeout (optional: the limits in the drive file are skipped)");
  }
  if (timeout && lim.following_error_timeout.count() >= 0) {
    p.plan.push_back("write following error timeout 0x6066 = " + std::to_string(lim.following_error_timeout.count()) + " ms");
  }
  if (vmax && lim.max_profile_velocity_rad_s > 0) p.plan.push_back("write max profile velocity 0x607F from the drive file");
  if (!vmax) p.lacks.push_back("0x607F max profile velocity (optional)");
  if (qs_option) {
    p.plan.push_back(std::string("quick stop option code 0x605A = ") + std::to_string(static_cast<std::int16_t>(*qs_option)) +
                     (*qs_option == 2 || *qs_option == 6 ? " (quick stop ramp)" : ""));
  } else {
    p.lacks.push_back("0x605A quick stop option code (optional: how the drive stops on quick stop is its maker's choice)");
  }
  if (cycle) {
    p.plan.push_back("0x1006 communication cycle period = the SYNC period");
  } else {
    p.lacks.push_back("0x1006 communication cycle period (optional: the drive is not told the SYNC period)");
  }
  if (qs_dec && lim.quick_stop_deceleration_rad_s2 > 0)
    p.plan.push_back("write quick stop deceleration 0x6085 from the drive file");
  if (!qs_dec) p.lacks.push_back("0x6085 quick stop deceleration (optional)");
  return p;
}

std::string Cia402Probe::report() const {
  std::string s;
  char line[256];
  std::snprintf(line, sizeof line, "device type 0x1000:00 = 0x%08X (CiA 402, %s)\n", device_type,
                ((device_type >> 16) & 0x02) ? "servo drive" : "drive");
  s += line;
  for (const auto& o : objects) {
    if (o.value) {
      std::snprintf(line, sizeof line, "  0x%04X:%02X %-32s 0x%08X (%u)\n", o.index, o.sub, o.name.c_str(), *o.value, *o.value);
    } else if (!o.no_answer.empty()) {
      std::snprintf(line, sizeof line, "  0x%04X:%02X %-32s no answer%s: ", o.index, o.sub, o.name.c_str(),
                    o.required ? " REQUIRED" : "");
      s += line;
      s += o.no_answer + "\n";
      continue;
    } else {
      std::snprintf(line, sizeof line, "  0x%04X:%02X %-32s absent (abort 0x%08X)%s\n", o.index, o.sub, o.name.c_str(),
                    o.abort_code, o.required ? " REQUIRED" : "");
    }
    s += line;
  }
  std::snprintf(
      line, sizeof line, "PDOs: %d RPDO, %d TPDO; cyclic synchronous position: %s\n", rpdos, tpdos,
      find(0x6502, 0) && find(0x6502, 0)->value ? (csp_supported ? "supported" : "NOT supported") : "not declared (no 0x6502)");
  s += line;
  s += "configure() will:\n";
  for (const auto& l : plan) s += "  - " + l + "\n";
  s += "the drive lacks:\n";
  if (lacks.empty()) s += "  (nothing the client uses)\n";
  for (const auto& l : lacks) s += "  - " + l + "\n";
  for (const auto& l : refused) s += "configure() will refuse: " + l + "\n";
  s += usable ? "verdict: usable by the CAN rig\n" : "verdict: NOT usable by the CAN rig\n";
  return s;
}

}  // namespace hil::drv
