// The `hybrid` rig kind: a real drive (CiA 402 on CAN or Modbus) whose encoder angle drives the
// campaign's backlash, valve and gas generator, simulated in the rig (a DeviceRig without a
// pressure sensor). The simulated chamber is what gives it a programmable gap and the truth.
#include "hil/bench/rt/device_rig.hpp"

HIL_REGISTER_RIG_KIND(
    hybrid, {.doc = "a real CiA 402 or Modbus drive; the campaign's backlash, valve and chamber simulated with its encoder",
             .capabilities = {.simulated = false, .programmable_gap = true, .knows_truth = true},
             .devices = {.drive = hil::bench::DriveNeed::cia402_or_modbus, .transducer = false},
             .make = &hil::bench::make_drive_and_simulated_chamber_rig})
