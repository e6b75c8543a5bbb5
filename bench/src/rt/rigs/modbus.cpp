// The `modbus` rig kind: a Modbus servo drive and a Modbus pressure transducer, composed as a
// DeviceRig. Both are polled by their clients: fresh while younger than their max_age_ms.
#include "hil/bench/rt/device_rig.hpp"

HIL_REGISTER_RIG_KIND(modbus, {.doc = "Modbus servo drive (TCP or RTU) + Modbus pressure transducer",
                               .devices = {.drive = true, .drive_client = "modbus", .transducer = true},
                               .make = &hil::bench::make_drive_and_transducer_rig})
