#include "hil/drv/clients.hpp"

#include <cmath>
#include <cstdio>
#include <optional>
#include <utility>

#include "hil/registry.hpp"

namespace hil::drv {
namespace {

template <class Part>
bool add(std::string_view key, ClientKind<Part> kind) {
  // The kind's view points at the registry's own copy of the name, which outlives every caller.
  auto [name, kept] = Registry<ClientKind<Part>>::add(key, kind);
  kept.key = name;
  return true;
}

// The one registered key `device` holds; the other keys are the client's to allow or refuse.
template <class Part>
const ClientKind<Part>& client_of(const cfg::Node& device, std::string_view what) {
  const std::vector<std::string> names = Registry<ClientKind<Part>>::names();
  std::string known;
  for (const auto& n : names) known += (known.empty() ? "" : ", ") + n;
  const ClientKind<Part>* found = nullptr;
  std::optional<std::pair<std::string, cfg::Node>> unknown;  // the first key that is no client
  for (const auto& [key, node] : device.entries()) {
    const ClientKind<Part>* kind = Registry<ClientKind<Part>>::find(key);
    if (kind == nullptr) {
      if (!unknown) unknown.emplace(key, node);
      continue;
    }
    if (found != nullptr) node.fail("names a second " + std::string(what) + " client: one of " + known);
    found = kind;
  }
  if (found == nullptr) {
    const std::string list = known.empty() ? "none" : known;
    // Located at a key close to a client's name, a typo of it; else at the device.
    const std::string hint = unknown ? cfg::closest(unknown->first, names) : std::string();
    if (!hint.empty()) {
      unknown->second.fail("unknown " + std::string(what) + " client '" + unknown->first + "' (did you mean '" + hint +
                           "'?); this build knows: " + list);
    }
    device.fail("needs one " + std::string(what) + " client: one of " + list);
  }
  return *found;
}

}  // namespace

bool register_drive_client(std::string_view key, DriveClientKind kind) { return add(key, kind); }
bool register_sensor_client(std::string_view key, SensorClientKind kind) { return add(key, kind); }
const DriveClientKind* find_drive_client(std::string_view key) { return Registry<DriveClientKind>::find(key); }
const SensorClientKind* find_sensor_client(std::string_view key) { return Registry<SensorClientKind>::find(key); }
std::vector<std::string> drive_client_names() { return Registry<DriveClientKind>::names(); }
std::vector<std::string> sensor_client_names() { return Registry<SensorClientKind>::names(); }
const DriveClientKind& drive_client_of(const cfg::Node& device) { return client_of<PositionDrive>(device, "drive"); }
const SensorClientKind& sensor_client_of(const cfg::Node& device) { return client_of<PressureSensor>(device, "sensor"); }

std::chrono::microseconds poll_max_age(const cfg::Node& device, std::chrono::milliseconds poll_period) {
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

}  // namespace hil::drv
