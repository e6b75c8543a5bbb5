// Fault tests of the CAN and Modbus rigs on the in-process loopback bus and Modbus TCP on
// 127.0.0.1 (rig_fault_scenarios.hpp; the CAN ones again on a real vcan0 in vcan_rigs_test.cpp).
#include <gtest/gtest.h>

#include "hil/drv/can_loopback.hpp"
#include "rig_fault_scenarios.hpp"

using namespace hil::test;

namespace {

class RigFaults : public ::testing::Test {
 protected:
  hil::drv::LoopbackBus bus;
  FaultSetup setup{bus.factory(), "vcan0", 1.0};
};

}  // namespace

TEST_F(RigFaults, HeartbeatLossReachesTheSafeStateAndIsReported) { heartbeat_loss(setup); }
TEST_F(RigFaults, SilentDriveTripsTheWatchdog) { drive_silent(setup); }
TEST_F(RigFaults, EmcyFaultTripsAndIsNamed) { emcy_fault(setup); }
TEST_F(RigFaults, BusOffIsDetectedReportedAndRecovered) { bus_off(setup); }
TEST_F(RigFaults, SdoAbortAtConfigureNamesTheObject) { sdo_abort(setup); }
TEST_F(RigFaults, AnAbortCutsTheRigSetupShort) { abort_during_setup(setup); }
TEST_F(RigFaults, ModbusTimeoutTripsThenReconnectsAndResumes) { modbus_timeout(setup); }
TEST_F(RigFaults, ModbusReadExceptionTripsTheWatchdogNamingTheException) { modbus_read_exception(setup); }
TEST_F(RigFaults, AFrozenCanEncoderTripsTheFollowingError) { frozen_encoder(setup, false); }
TEST_F(RigFaults, AFrozenModbusEncoderTripsTheFollowingError) { frozen_encoder(setup, true); }
