// A rig file (configs/rigs/*.yaml, documented in place): which rig, its devices, its loop
// (priority, CPU, overrun policy) and its safety interlocks. Validated at load, the device files
// included: errors name file:line:key.
#pragma once

#include <filesystem>
#include <memory>
#include <string>

#include "hil/bench/rt/rig.hpp"
#include "hil/bench/rt/rt_loop.hpp"
#include "hil/bench/rt/safety.hpp"
#include "hil/drv/can.hpp"
#include "hil/drv/clients.hpp"

namespace hil::bench {

struct RigKindInfo;

// The `devices` block of the can, modbus and hybrid rigs: the drive's and the transducer's
// clients, each by its registered key (hil/drv/clients.hpp) with its configuration validated into
// a recipe the rig makes the client from at configure (and the client's age limit, if polled).
struct RigDevices {
  std::string drive_client;                             // devices.drive's client key ("cia402"); empty: none
  std::shared_ptr<const drv::DriveRecipe> drive;        // null: none
  std::string transducer_client;                        // devices.transducer's client key ("modbus"); empty: none
  std::shared_ptr<const drv::SensorRecipe> transducer;  // null: none (the rig simulates the chamber)
  // The drive client's configuration as read, when it is a `Config` (the probe: drv::Cia402Config);
  // nullptr when there is no drive or another client's.
  template <class Config>
  const Config* drive_config() const {
    const auto* r = dynamic_cast<const drv::ConfigRecipe<drv::PositionDrive, Config>*>(drive.get());
    return r == nullptr ? nullptr : &r->config;
  }
  template <class Config>
  const Config* transducer_config() const {
    const auto* r = dynamic_cast<const drv::ConfigRecipe<drv::PressureSensor, Config>*>(transducer.get());
    return r == nullptr ? nullptr : &r->config;
  }
};

struct RigConfig {
  std::string name;  // the file's stem
  std::string kind;  // a registered rig kind (rig_registry.hpp): sim, can, modbus, hybrid, ...
  std::string description;
  std::filesystem::path file;
  RigDevices devices;  // empty for sim
  LoopConfig loop;
  SafetyConfig safety;
  // The run needs a console or ctl client: none heard for operator_timeout_s and it goes to its
  // safe state, reason "operator link lost" (server/operator_link.hpp). Off by default.
  bool require_operator = false;
  double operator_timeout_s = 5.0;
  std::string yaml_text;  // the file as loaded, for the run's snapshot
};

RigConfig load_rig_config(const std::filesystem::path& file);
// What an operator should know before a run on this rig, in words; empty when nothing. Today: a
// rig with a real drive and no safety.following_error, where a drive that stops following (a
// frozen encoder, a jammed gear) is caught by no interlock.
std::string rig_warning(const RigConfig& config);
RigConfig load_rig_config_text(const std::string& yaml, const std::string& origin);

// A new, unconfigured rig of the file's kind, made by the kind's registered recipe
// (rig_registry.hpp; opens nothing yet). `can_transport` carries the CAN rigs' frames (tests:
// drv::LoopbackBus::factory()); empty: SocketCAN on the drive's interface. Throws naming the file
// and the kind, the kinds this build knows and the closest, when it is unknown.
std::unique_ptr<Rig> make_rig(const RigConfig& config, const drv::CanTransportFactory& can_transport = {});
// The file's kind as registered (what it can do, which devices it takes, how it is made). Throws
// std::invalid_argument naming the file when the kind is unknown.
const RigKindInfo& kind_of(const RigConfig& config);

}  // namespace hil::bench
