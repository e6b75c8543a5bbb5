// Rig kinds are created by name, as plant effects are: a kind registers itself with
// HIL_REGISTER_RIG_KIND in its own .cpp under bench/src/rt/rigs/ (globbed; the folder is
// linked whole, see bench/CMakeLists.txt), declaring what it can do and which devices its rig
// file names. The rig file's validation (rig_config.cpp) and make_rig() ask this table, so a new
// kind is that one file plus its YAML in configs/rigs/.
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "hil/bench/rt/rig.hpp"
#include "hil/drv/can.hpp"

namespace hil::bench {

struct RigConfig;

// What a rig of this kind can do; Rig::simulated()/programmable_gap()/knows_truth() answer the same.
struct RigCapabilities {
  bool simulated = false;         // no hardware in the loop: any speed, faults faked on purpose
  bool programmable_gap = false;  // RigCommand::gap_rad sets the true backlash
  bool knows_truth = false;       // readings carry the valve angle and the chamber pressure
};

// The devices a kind's rig file names under `devices`, each a client registered in the drivers
// by its key (hil/drv/clients.hpp): `drive: {cia402: ...}`, `transducer: {modbus: ...}`.
struct RigDeviceNeeds {
  bool drive = false;               // devices.drive; false: the rig simulates the drive
  std::string_view drive_client{};  // the one drive client the kind takes ("cia402"); empty: any registered
  bool transducer = false;          // devices.transducer; false: the rig simulates the chamber
};

// What a rig with devices can do follows from them: the simulated valve and chamber behind a
// drive without a transducer (hybrid) is what makes the gap programmable and the truth known.
// register_rig_kind() sets a device kind's capabilities from this: they are declared once.
constexpr RigCapabilities capabilities_of(const RigDeviceNeeds& devices) {
  return {.simulated = false, .programmable_gap = !devices.transducer, .knows_truth = !devices.transducer};
}

struct RigKindInfo {
  std::string_view kind{};  // the rig file's `kind:`; set by HIL_REGISTER_RIG_KIND from its first argument
  std::string_view doc;     // one line, for listings
  // Declared by a kind without devices (sim); a kind with a drive gets capabilities_of(devices).
  RigCapabilities capabilities{};
  RigDeviceNeeds devices{};
  // A new, unconfigured rig of this kind from its validated file (opens nothing; the clients open
  // their devices at configure). `can_transport` carries CAN frames (empty: SocketCAN).
  std::unique_ptr<Rig> (*make)(const RigKindInfo& self, const RigConfig& config, const drv::CanTransportFactory& can_transport);
};

// Setup (static initialisation): adds `info` under `kind`. A second kind of the same name is
// ignored (the first stays), as for effects. Returns true, for the registrar constant.
bool register_rig_kind(std::string_view kind, RigKindInfo info);
// nullptr when unknown.
const RigKindInfo* find_rig_kind(std::string_view kind);
// The kinds this build knows, sorted by name.
std::vector<std::string> rig_kind_names();
// "unknown rig kind 'cann' (did you mean 'can'?); this build knows: can, hybrid, modbus, sim"
std::string unknown_rig_kind_text(std::string_view kind);

}  // namespace hil::bench

// In a kind's .cpp, at namespace scope: HIL_REGISTER_RIG_KIND(can, {.doc = "...", .devices =
// {...}, .make = &make_can_rig}) (a kind without devices: .capabilities = {...} instead). The first argument is the kind's name as the
// rig file spells it (an identifier).
#define HIL_REGISTER_RIG_KIND(name, ...)                                             \
  namespace {                                                                        \
  [[maybe_unused]] const bool registered_rig_kind_##name =                           \
      ::hil::bench::register_rig_kind(#name, ::hil::bench::RigKindInfo __VA_ARGS__); \
  }
