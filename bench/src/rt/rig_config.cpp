#include "hil/bench/rt/rig_config.hpp"

#include <algorithm>
#include <cstdio>

#include "hil/bench/rt/rig_registry.hpp"
#include "hil/config.hpp"

namespace hil::bench {
namespace {

// `{cia402: FILE | {...}}` and the like: a device's client configuration from its file (paths
// relative to the rig file) or inline.
template <class Config>
Config device_config(const cfg::Node& n) {
  if (n.is_scalar()) return Config::load(n.resolve_path(n.text()));
  return Config::from_yaml(n);
}

// A Modbus device's age limit: max_age_ms, or two polls. A reading is up to one poll period old
// (plus its reply's time) when the next one arrives, so a limit at or below the poll period is a
// device stale at every poll: refused, naming both. Given or by default, at most 60 s: a slower
// device is no feedback for a control loop (poll_period_ms alone may be up to 600 s).
std::chrono::microseconds max_age(const cfg::Node& device, std::chrono::milliseconds poll_period) {
  constexpr double kLimitMs = 60000;
  const double poll_ms = static_cast<double>(poll_period.count());
  const auto key = device.find("max_age_ms");
  if (!key) {
    if (2 * poll_ms > kLimitMs) {
      device.fail("the default max_age_ms, two polls of poll_period_ms " + std::to_string(poll_period.count()) +
                  ", is past the 60000 ms limit: poll faster");
    }
    return 2 * poll_period;
  }
  const double ms = key->number();
  key->require(ms > 0 && ms <= kLimitMs, "must be > 0 and <= 60000 ms");
  if (ms <= poll_ms) {
    char given[32];
    std::snprintf(given, sizeof given, "%g", ms);
    key->fail("max_age_ms " + std::string(given) + " is not above the device's poll_period_ms " +
              std::to_string(poll_period.count()) +
              ": a reading is up to one poll old before the next arrives, so it would be stale at every poll");
  }
  return std::chrono::microseconds(std::lround(ms * 1000));
}

bool takes_cia402(DriveNeed n) { return n == DriveNeed::cia402 || n == DriveNeed::cia402_or_modbus; }
bool takes_modbus(DriveNeed n) { return n == DriveNeed::modbus || n == DriveNeed::cia402_or_modbus; }

// The `devices` block as the kind declares it (RigKindInfo::devices).
RigDevices devices_from(const cfg::Node& root, const std::string& kind, const RigDeviceNeeds& needs) {
  RigDevices d;
  if (needs.drive == DriveNeed::none && !needs.transducer) {
    if (root.has("devices"))
      root.at("devices").fail("the " + kind + " rig has no devices (it simulates the drive and the transducer)");
    return d;
  }
  const cfg::Node devices = root.at("devices");
  devices.allow_keys({"drive", "transducer"});
  if (needs.drive == DriveNeed::none) {
    if (devices.has("drive")) devices.at("drive").fail("the " + kind + " rig simulates the drive: it takes no drive");
  } else {
    const cfg::Node drive = devices.at("drive");
    drive.allow_keys({"cia402", "modbus", "max_age_ms"});
    if (drive.has("cia402") == drive.has("modbus")) drive.fail("needs one of cia402 (a CiA 402 drive on CAN) or modbus");
    if (drive.has("cia402")) {
      if (!takes_cia402(needs.drive)) drive.at("cia402").fail("the " + kind + " rig needs a Modbus drive (drive: {modbus: ...})");
      if (drive.has("max_age_ms")) {
        drive.at("max_age_ms")
            .fail("a CAN drive's feedback is stale when no TPDO arrived since the last SYNC; no age limit to set");
      }
      d.can_drive = device_config<drv::Cia402Config>(drive.at("cia402"));
    } else {
      if (!takes_modbus(needs.drive))
        drive.at("modbus").fail("the " + kind + " rig needs a CiA 402 drive (drive: {cia402: ...})");
      d.modbus_drive = device_config<drv::ModbusDriveConfig>(drive.at("modbus"));
      d.drive_max_age = max_age(drive, d.modbus_drive->link.poll_period);
    }
  }
  if (!needs.transducer) {
    if (devices.has("transducer")) {
      devices.at("transducer")
          .fail("the " + kind + " rig simulates the chamber: its pressure comes from the plant, not a transducer");
    }
    return d;
  }
  const cfg::Node transducer = devices.at("transducer");
  transducer.allow_keys({"modbus", "max_age_ms"});
  d.transducer = device_config<drv::ModbusTransducerConfig>(transducer.at("modbus"));
  d.transducer_max_age = max_age(transducer, d.transducer->link.poll_period);
  return d;
}

RigConfig from_node(const cfg::Node& root, std::string name, std::string text) {
  root.allow_keys({"kind", "description", "devices", "loop", "safety", "require_operator", "operator_timeout_s"});
  RigConfig c;
  c.name = std::move(name);
  c.file = root.file();
  c.yaml_text = std::move(text);
  c.kind = root.text("kind");
  const RigKindInfo* kind = find_rig_kind(c.kind);
  if (kind == nullptr) root.at("kind").fail(unknown_rig_kind_text(c.kind));
  c.description = root.text("description", "");
  c.devices = devices_from(root, c.kind, kind->devices);
  if (const auto loop = root.find("loop")) c.loop = LoopConfig::from_yaml(*loop);
  c.safety = SafetyConfig::from_yaml(root.at("safety"));
  c.require_operator = root.boolean("require_operator", false);
  if (const auto t = root.find("operator_timeout_s")) {
    c.operator_timeout_s = t->number();
    // Under 0.5 s a console's once-a-second status poll would not keep the link; over an hour is no
    // watch at all.
    t->require(c.operator_timeout_s >= 0.5 && c.operator_timeout_s <= 3600, "must be 0.5..3600 s");
  }
  // The fastest this rig moves a CAN drive's target: configure() and the probe check the drive's
  // following error window against it (drv::following_window_problem).
  if (c.devices.can_drive) {
    const double rate = c.safety.rate_limit_rad_s;
    c.devices.can_drive->target_velocity_rad_s =
        c.loop.target_shaping.enabled() ? std::min(c.loop.target_shaping.max_velocity_rad_s, rate) : rate;
  }
  return c;
}

}  // namespace

std::string rig_warning(const RigConfig& config) {
  const bool real_drive = config.devices.can_drive.has_value() || config.devices.modbus_drive.has_value();
  if (!real_drive || config.safety.watches_following()) return {};
  return "rig '" + config.name +
         "' drives a real motor without safety.following_error: a drive that stops following its target (a frozen "
         "encoder, a jammed gear) trips no interlock; set following_error: {max_deg, time_ms} (the shipped drive rigs: "
         "3 deg, 100 ms)";
}

RigConfig load_rig_config(const std::filesystem::path& file) {
  std::string text;
  const cfg::Node root = cfg::Node::load_file(file, &text);
  return from_node(root, file.stem().string(), text);
}

RigConfig load_rig_config_text(const std::string& yaml, const std::string& origin) {
  return from_node(cfg::Node::load_string(yaml, origin), std::filesystem::path(origin).stem().string(), yaml);
}

const RigKindInfo& kind_of(const RigConfig& config) {
  const RigKindInfo* kind = find_rig_kind(config.kind);
  if (kind == nullptr) throw std::invalid_argument(config.file.string() + ": " + unknown_rig_kind_text(config.kind));
  return *kind;
}

std::unique_ptr<Rig> make_rig(const RigConfig& config, const drv::CanTransportFactory& can_transport) {
  const RigKindInfo& kind = kind_of(config);
  return kind.make(kind, config, can_transport);
}

}  // namespace hil::bench
