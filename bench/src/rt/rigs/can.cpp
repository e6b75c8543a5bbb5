// The `can` rig kind: a CiA 402 drive on CAN and a Modbus pressure transducer, composed as a
// DeviceRig. The loop's write sends the drive's SYNC, so its feedback is fresh when a TPDO arrived
// after the last write; the transducer's while it is younger than its max_age_ms.
#include "hil/bench/rt/device_rig.hpp"

HIL_REGISTER_RIG_KIND(can, {.doc = "CiA 402 servo on SocketCAN (SYNC at the loop rate) + Modbus pressure transducer",
                            .devices = {.drive = true, .drive_client = "cia402", .transducer = true},
                            .make = &hil::bench::make_drive_and_transducer_rig})
