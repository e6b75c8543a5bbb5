#include "hil/bench/rt/rig_config.hpp"

#include <algorithm>

#include "hil/bench/rt/rig_registry.hpp"
#include "hil/config.hpp"

namespace hil::bench {
namespace {

// The `devices` block as the kind declares it (RigKindInfo::devices), each device's client by its
// registered key (hil/drv/clients.hpp), loaded by that client.
RigDevices devices_from(const cfg::Node& root, const std::string& kind, const RigDeviceNeeds& needs,
                        double target_velocity_rad_s) {
  RigDevices d;
  if (!needs.drive && !needs.transducer) {
    if (root.has("devices"))
      root.at("devices").fail("the " + kind + " rig has no devices (it simulates the drive and the transducer)");
    return d;
  }
  const cfg::Node devices = root.at("devices");
  devices.allow_keys({"drive", "transducer"});
  if (!needs.drive) {
    if (devices.has("drive")) devices.at("drive").fail("the " + kind + " rig simulates the drive: it takes no drive");
  } else {
    const cfg::Node drive = devices.at("drive");
    const drv::DriveClientKind& client = drv::drive_client_of(drive);
    if (!needs.drive_client.empty() && client.key != needs.drive_client) {
      const drv::DriveClientKind* wanted = drv::find_drive_client(needs.drive_client);
      drive.at(client.key)
          .fail("the " + kind + " rig needs " + (wanted != nullptr ? std::string(wanted->doc) : "another drive") + " (drive: {" +
                std::string(needs.drive_client) + ": ...})");
    }
    d.drive_client = client.key;
    d.drive = client.load({drive, drive.at(client.key), target_velocity_rad_s});
  }
  if (!needs.transducer) {
    if (devices.has("transducer")) {
      devices.at("transducer")
          .fail("the " + kind + " rig simulates the chamber: its pressure comes from the plant, not a transducer");
    }
    return d;
  }
  const cfg::Node transducer = devices.at("transducer");
  const drv::SensorClientKind& client = drv::sensor_client_of(transducer);
  d.transducer_client = client.key;
  d.transducer = client.load({transducer, transducer.at(client.key), 0.0});
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
  if (const auto loop = root.find("loop")) c.loop = LoopConfig::from_yaml(*loop);
  c.safety = SafetyConfig::from_yaml(root.at("safety"));
  // The fastest this rig moves a drive's target, for a client that checks its drive's following
  // error window against it (the CiA 402 client: configure() and the probe).
  const double rate = c.safety.rate_limit_rad_s;
  const double target_velocity_rad_s =
      c.loop.target_shaping.enabled() ? std::min(c.loop.target_shaping.max_velocity_rad_s, rate) : rate;
  c.devices = devices_from(root, c.kind, kind->devices, target_velocity_rad_s);
  c.require_operator = root.boolean("require_operator", false);
  if (const auto t = root.find("operator_timeout_s")) {
    c.operator_timeout_s = t->number();
    // Under 0.5 s a console's once-a-second status poll would not keep the link; over an hour is no
    // watch at all.
    t->require(c.operator_timeout_s >= 0.5 && c.operator_timeout_s <= 3600, "must be 0.5..3600 s");
  }
  return c;
}

}  // namespace

std::string rig_warning(const RigConfig& config) {
  const bool real_drive = config.devices.drive != nullptr;
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
