// paper_adaptive through `hilbench serve` on the Modbus rig against `hilbench plant` on loopback
// TCP, real time at 1 kHz: the two processes run the campaign to the end, every row on disk, the
// devices connected. Real time on a shared machine holds no period for sure, so the watchdog and
// the devices' timeouts are set to stalls, not periods, and the trace is printed, not bounded: its
// equivalence with the simulation is ModbusRig.ShortPaperInLockstepMatchesTheSimulation
// (rigs_test.cpp, simulated time); 1 kHz figures are benchmarks. (The CAN rig's run is in
// vcan_rigs_test.cpp, on a real vcan0.)
#include <gtest/gtest.h>

#include "serve_e2e.hpp"

using namespace hil::test;

TEST(ServeEndToEnd, PaperAdaptiveOnTheModbusRigRunsThrough) {
  RigOptions o;
  o.watchdog_misses = 1000000;  // never within the run
  const ServeResult r = serve_paper_adaptive(1.0, {"--modbus", "tcp:127.0.0.1:0"}, [&](const PlantProcess& p) {
    return rig_yaml("modbus", modbus_device_yaml(p.drive_port(), "modbus_drive_map.yaml", 4, 2000),
                    modbus_device_yaml(p.transducer_port(), "modbus_transducer_map.yaml", 4, 2000), o);
  });
  EXPECT_EQ(r.run["rig"]["kind"], "modbus");
  EXPECT_TRUE(r.run["rig_health"]["connected"].get<bool>()) << r.run["rig_health"];
}
