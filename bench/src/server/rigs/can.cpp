// The `can` rig kind: a CiA 402 drive on CAN and a Modbus pressure transducer, composed as a
// DeviceRig. The loop's write sends the drive's SYNC, so its feedback is fresh when a TPDO arrived
// after the last write; the transducer's while it is younger than its max_age_ms.
#include "hil/bench/device_rig.hpp"

namespace {
using namespace hil::bench;

std::unique_ptr<Rig> make_can_rig(const RigKindInfo& self, const RigConfig& config, const hil::drv::CanTransportFactory& can_transport) {
  return std::make_unique<DeviceRig>(config, self,
                                     DeviceRig::Parts{.drive = drive_from_file(config, can_transport),
                                                      .drive_max_age = config.devices.drive_max_age,
                                                      .pressure_sensor = transducer_from_file(config),
                                                      .sensor_max_age = config.devices.transducer_max_age});
}
}  // namespace

HIL_REGISTER_RIG_KIND(can, {.doc = "CiA 402 servo on SocketCAN (SYNC at the loop rate) + Modbus pressure transducer",
                            .capabilities = {.simulated = false, .programmable_gap = false, .knows_truth = false},
                            .devices = {.drive = hil::bench::DriveNeed::cia402, .transducer = true},
                            .make = &make_can_rig})
