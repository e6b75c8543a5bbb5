// The `hybrid` rig kind: a real drive (any registered drive client, hil/drv/clients.hpp) whose encoder angle drives the
// campaign's backlash, valve and gas generator, simulated in the rig (a DeviceRig without a
// pressure sensor). The simulated chamber is what gives it a programmable gap and the truth.
#include "hil/bench/rt/device_rig.hpp"

HIL_REGISTER_RIG_KIND(hybrid, {.doc = "a real drive (any drive client: CiA 402, Modbus, ...); the campaign's backlash, valve and "
                                      "chamber simulated with its encoder",
                               .devices = {.drive = true, .transducer = false},
                               .make = &hil::bench::make_drive_and_simulated_chamber_rig})
