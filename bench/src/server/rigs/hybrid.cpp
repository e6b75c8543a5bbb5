// The `hybrid` rig kind: a real drive (CiA 402 on CAN or Modbus) whose encoder angle drives the
// campaign's backlash, valve and gas generator, simulated in the rig (a DeviceRig without a
// pressure sensor). The simulated chamber is what gives it a programmable gap and the truth.
#include "hil/bench/device_rig.hpp"

namespace {
using namespace hil::bench;

std::unique_ptr<Rig> make_hybrid_rig(const RigKindInfo& self, const RigConfig& config,
                                     const hil::drv::CanTransportFactory& can_transport) {
  return std::make_unique<DeviceRig>(config, self,
                                     DeviceRig::Parts{.drive = drive_from_file(config, can_transport),
                                                      .drive_max_age = config.devices.drive_max_age,
                                                      .pressure_sensor = {},
                                                      .sensor_max_age = {}});
}
}  // namespace

HIL_REGISTER_RIG_KIND(hybrid, {.doc = "a real CiA 402 or Modbus drive; the campaign's backlash, valve and chamber simulated with its encoder",
                               .capabilities = {.simulated = false, .programmable_gap = true, .knows_truth = true},
                               .devices = {.drive = hil::bench::DriveNeed::cia402_or_modbus, .transducer = false},
                               .make = &make_hybrid_rig})
