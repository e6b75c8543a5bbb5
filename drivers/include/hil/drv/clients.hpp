// Device clients are created by the key a rig file names them with, as plant effects and rig kinds
// are: a client registers itself with HIL_REGISTER_DRIVE_CLIENT or HIL_REGISTER_SENSOR_CLIENT in
// its own .cpp under drivers/src/clients/ (globbed and linked whole, see drivers/CMakeLists.txt),
// with a loader that validates its YAML and returns a recipe. The rig file's `devices` block
// (bench/src/rt/rig_config.cpp) and the device rig ask this table only, so a new drive or sensor
// client is that one file plus its tests:
//
//   devices:
//     drive:      {cia402: FILE | {...}}          a registered drive client's key, its configuration
//     transducer: {modbus: FILE | {...}, max_age_ms: 8}
#pragma once

#include <chrono>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "hil/config.hpp"
#include "hil/drv/can.hpp"
#include "hil/drv/parts.hpp"

namespace hil::drv {

// What a client is made with at the rig's configure (not at load: a client may open its channel
// when constructed, and a CAN drive takes the run's period as its SYNC period).
struct DeviceSetup {
  double period_s = 1e-3;  // the loop's period
  // The rig's watchdog time (safety.watchdog_misses x the period; 0: none): a drive client that
  // watches the loop's liveness (Cia402Config::loop_hang_bound, ModbusDriveConfig's) allows at least this.
  double watchdog_s = 0;
  CanTransportFactory can_transport;  // CAN clients: carries the frames (empty: SocketCAN on the configured interface)
};

// A client's configuration as validated from a rig file (its device files included): the recipe
// the rig makes the client from, once per configure.
template <class Part>
class DeviceRecipe {
 public:
  virtual ~DeviceRecipe() = default;
  // A new client, unconfigured; throws naming the device when it cannot be made.
  virtual std::unique_ptr<Part> make(const DeviceSetup& setup) const = 0;
  // Polled parts: a value older than this is stale (the rig file's max_age_ms, or two polls).
  // Zero for a drive whose freshness is FeedbackFreshness::reply_to_each_write.
  std::chrono::microseconds max_age{0};
};
using DriveRecipe = DeviceRecipe<PositionDrive>;
using SensorRecipe = DeviceRecipe<PressureSensor>;

// The recipe of a client with a configuration struct, kept as read: what a tool that knows the
// client needs of it (the CiA 402 probe takes the drive's Cia402Config from a rig file).
template <class Part, class Config>
class ConfigRecipe : public DeviceRecipe<Part> {
 public:
  explicit ConfigRecipe(Config c) : config(std::move(c)) {}
  Config config;
};

// What a loader gets: the device's node (`devices.drive`: the client key and the keys beside it,
// such as max_age_ms) and the client's own (its value: a file name relative to the rig file, or
// the mapping inline).
struct DeviceNodes {
  cfg::Node device;
  cfg::Node client;
  // The fastest the rig moves a drive's target (rad/s; from its loop.target_shaping and
  // safety.rate_limit): a client that checks its drive's following error window against it.
  double target_velocity_rad_s = 0;
};

template <class Part>
struct ClientKind {
  std::string_view key{};  // the YAML key; set by the registration macro from its first argument
  std::string_view doc;    // what it talks to, as an error message names it: "a CiA 402 drive on CAN"
  // Validates the device's nodes (throws cfg::Error naming file:line:key) and returns the recipe.
  std::shared_ptr<const DeviceRecipe<Part>> (*load)(const DeviceNodes& nodes);
};
using DriveClientKind = ClientKind<PositionDrive>;
using SensorClientKind = ClientKind<PressureSensor>;

// Setup (static initialisation): adds a client under `key`; the first of a name wins. Returns
// true, for the registrar constant.
bool register_drive_client(std::string_view key, DriveClientKind kind);
bool register_sensor_client(std::string_view key, SensorClientKind kind);
const DriveClientKind* find_drive_client(std::string_view key);  // nullptr when unknown
const SensorClientKind* find_sensor_client(std::string_view key);
std::vector<std::string> drive_client_names();  // sorted
std::vector<std::string> sensor_client_names();

// The registered client `device` names (exactly one of the registered keys, beside whatever
// else the client allows); throws cfg::Error naming the node, the keys this build knows and the
// closest one to an unknown key.
const DriveClientKind& drive_client_of(const cfg::Node& device);
const SensorClientKind& sensor_client_of(const cfg::Node& device);

// Helpers for loaders.
// `{key: FILE | {...}}`: the client's configuration from its own file (a path relative to the rig
// file; Config::load) or inline (Config::from_yaml).
template <class Config>
Config client_config(const cfg::Node& client) {
  if (client.is_scalar()) return Config::load(client.resolve_path(client.text()));
  return Config::from_yaml(client);
}
// A polled device's age limit: `device`'s max_age_ms, or two polls. A reading is up to one poll
// old (plus its reply's time) when the next one arrives, so a limit at or below the poll period
// is a device stale at every poll: refused, naming both. At most 60 s: a slower device is no
// feedback for a control loop.
std::chrono::microseconds poll_max_age(const cfg::Node& device, std::chrono::milliseconds poll_period);

}  // namespace hil::drv

// In a client's .cpp, at namespace scope: HIL_REGISTER_DRIVE_CLIENT(cia402, {.doc = "a CiA 402
// drive on CAN", .load = &load}). The first argument is the key as the rig file spells it.
#define HIL_REGISTER_DRIVE_CLIENT(name, ...)                                             \
  namespace {                                                                            \
  [[maybe_unused]] const bool registered_drive_client_##name =                           \
      ::hil::drv::register_drive_client(#name, ::hil::drv::DriveClientKind __VA_ARGS__); \
  }
#define HIL_REGISTER_SENSOR_CLIENT(name, ...)                                              \
  namespace {                                                                              \
  [[maybe_unused]] const bool registered_sensor_client_##name =                            \
      ::hil::drv::register_sensor_client(#name, ::hil::drv::SensorClientKind __VA_ARGS__); \
  }
