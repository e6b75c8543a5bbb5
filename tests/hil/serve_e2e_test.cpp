// paper_adaptive through `hilbench serve` on the Modbus rig against `hilbench plant` on loopback
// TCP, real time at 1 kHz: the pressure trace is the pure simulation's within 2 % of the pressure
// range RMS. (The CAN rig's run is in vcan_rigs_test.cpp, on a real vcan0.)
#include <gtest/gtest.h>

#include "serve_e2e.hpp"

using namespace hil::test;

TEST(ServeEndToEnd, PaperAdaptiveOnTheModbusRigMatchesTheSimulation) {
  const ServeResult r = serve_paper_adaptive(1.0, {"--modbus", "tcp:127.0.0.1:0"}, [](const PlantProcess& p) {
    return rig_yaml("modbus", modbus_device_yaml(p.drive_port(), "modbus_drive_map.yaml"),
                    modbus_device_yaml(p.transducer_port(), "modbus_transducer_map.yaml"));
  });
  EXPECT_LT(r.diff.percent, 2.0);
  EXPECT_EQ(r.run["rig"]["kind"], "modbus");
  EXPECT_TRUE(r.run["rig_health"]["connected"].get<bool>()) << r.run["rig_health"];
}
