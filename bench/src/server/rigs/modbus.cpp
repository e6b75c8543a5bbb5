// The `modbus` rig kind: a Modbus servo drive and a Modbus pressure transducer, composed as a
// DeviceRig. Both are polled by their clients: fresh while younger than their max_age_ms.
#include "hil/bench/device_rig.hpp"

namespace {
using namespace hil::bench;

std::unique_ptr<Rig> make_modbus_rig(const RigKindInfo& self, const RigConfig& config,
                                     const hil::drv::CanTransportFactory& can_transport) {
  return std::make_unique<DeviceRig>(config, self,
                                     DeviceRig::Parts{.drive = drive_from_file(config, can_transport),
                                                      .drive_max_age = config.devices.drive_max_age,
                                                      .pressure_sensor = transducer_from_file(config),
                                                      .sensor_max_age = config.devices.transducer_max_age});
}
}  // namespace

HIL_REGISTER_RIG_KIND(modbus, {.doc = "Modbus servo drive (TCP or RTU) + Modbus pressure transducer",
                               .capabilities = {.simulated = false, .programmable_gap = false, .knows_truth = false},
                               .devices = {.drive = hil::bench::DriveNeed::modbus, .transducer = true},
                               .make = &make_modbus_rig})
