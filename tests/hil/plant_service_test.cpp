// The plant behind the device emulators, driven by the bench's real clients: a CiA 402 drive on
// the in-process loopback bus, and a Modbus drive and transducer over TCP on 127.0.0.1.
#include <gtest/gtest.h>

#include <limits>

#include "drivers/cia402_scenarios.hpp"
#include "hil/bench/rt/plant_service.hpp"
#include "hil/drv/can_loopback.hpp"
#include "hil/drv/modbus.hpp"
#include "hil/drv/modbus_emulator.hpp"
#include "hil/units.hpp"
#include "support/temp_file.hpp"

using namespace hil;
using namespace std::chrono_literals;
using drv::test::eventually;
using units::deg_to_rad;

namespace {

bench::PlantServiceConfig nominal(double p_mpa = 1.0) {
  bench::PlantServiceConfig c;
  c.plant = std::make_shared<const plant::Plant>(plant::Plant::load(test::source_path("configs/plant/nominal.yaml")));
  c.p_initial_pa = units::mpa_to_pa(p_mpa);
  return c;
}

drv::ModbusLinkConfig tcp(int port) {
  drv::ModbusLinkConfig l;
  l.host = "127.0.0.1";
  l.port = port;
  l.response_timeout = 500ms;
  return l;
}

TEST(PlantService, StartsInSteadyStateOnTheOpeningFlank) {
  bench::PlantService service(nominal(1.0));
  const auto s = service.sample();
  EXPECT_NEAR(s.p_chamber_pa, 1e6, 1.0);
  EXPECT_NEAR(units::rad_to_deg(s.theta_motor_rad - s.theta_valve_rad), 0.5, 1e-9);  // half the 1 deg gap
}

// stop() (SIGINT/SIGTERM of `hilbench plant`) joined a plant thread asleep until its next
// deadline: with the longest period a campaign allows, 1 s, it waited up to that long (with an
// unbounded --period-ms, for ever). The plant thread's wait now ends at stop(). Measured here
// 50 ms into a 1 s period; the old stop took the remaining 0.95 s.
TEST(PlantService, StopDoesNotWaitOutThePeriod) {
  auto config = nominal(1.0);
  config.period_s = 1.0;
  bench::PlantService service(config);
  service.start();
  std::this_thread::sleep_for(50ms);
  const auto t0 = std::chrono::steady_clock::now();
  service.stop();
  const auto took = std::chrono::steady_clock::now() - t0;
  EXPECT_LT(took, 300ms) << std::chrono::duration<double, std::milli>(took).count() << " ms";
}

// Opening the valve by 2 deg through a CiA 402 drive lowers the pressure the transducer reports.
TEST(PlantService, CanDriveMovesThePlant) {
  bench::PlantService service(nominal(1.0));
  drv::LoopbackBus bus;
  auto cfg = drv::test::test_config(7);
  drv::Cia402DriveEmulator emulator(drv::Cia402EmulatorConfig{cfg.interface, cfg.node_id, cfg.units}, service.add_drive(),
                                    bus.factory());
  drv::Cia402Drive client(cfg, bus.factory());
  service.start();
  client.configure();
  client.activate();
  drv::test::TestLoop loop(client);
  const double start = service.sample().theta_motor_rad;
  ASSERT_TRUE(eventually([&] { return std::abs(loop.position_rad.load() - start) < deg_to_rad(0.01); }));
  loop.target_rad = start + deg_to_rad(2.0);
  // 2 deg at 60 deg/s plus the lag: the motor gets there within a second, the valve opens 2 deg.
  ASSERT_TRUE(
      eventually([&] { return std::abs(service.sample().theta_motor_rad - (start + deg_to_rad(2.0))) < deg_to_rad(0.01); }, 5s));
  std::this_thread::sleep_for(800ms);  // several chamber time constants
  const auto s = service.sample();
  EXPECT_NEAR(units::rad_to_deg(s.theta_valve_rad - s.theta_motor_rad), -0.5, 1e-6);  // still on the opening flank
  EXPECT_LT(s.p_chamber_pa, 0.93e6);                                                  // 13 deg instead of 11 deg: about 0.88 MPa
  EXPECT_NEAR(loop.position_rad.load(), s.theta_motor_rad, deg_to_rad(0.05));         // the encoder reports the motor
}

// Any Modbus master may write a float target register NaN or inf: the plant must not step into
// it (one NaN step makes the motor, the valve and the chamber NaN for the rest of the process).
// It holds the motor where it is, as for a disabled drive, and follows the next real target.
TEST(PlantService, ATargetThatIsNoNumberHoldsTheMotor) {
  bench::PlantService service(nominal(1.0));
  drv::DriveModel& drive = service.add_drive();
  service.start();
  const double start = service.sample().theta_motor_rad;
  drive.command(start + deg_to_rad(1.0), true);
  ASSERT_TRUE(
      eventually([&] { return std::abs(service.sample().theta_motor_rad - (start + deg_to_rad(1.0))) < deg_to_rad(0.01); }, 5s));
  for (double bad : {plant::kNaN, std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()}) {
    drive.command(bad, true);
    const std::uint64_t steps = service.sample().steps;
    ASSERT_TRUE(eventually([&] { return service.sample().steps > steps + 50; }));  // 50 plant steps with it
    const auto s = service.sample();
    EXPECT_NEAR(s.theta_motor_rad, start + deg_to_rad(1.0), deg_to_rad(0.01)) << bad;
    EXPECT_TRUE(std::isfinite(s.p_chamber_pa) && std::isfinite(s.p_meas_pa) && std::isfinite(s.theta_valve_rad)) << bad;
  }
  drive.command(start, true);
  EXPECT_TRUE(eventually([&] { return std::abs(service.sample().theta_motor_rad - start) < deg_to_rad(0.01); }, 5s));
}

// The same with the Modbus drive and transducer clients, and a gap programme on the plant's clock.
TEST(PlantService, ModbusDriveAndTransducerWithAGapProgramme) {
  auto config = nominal(1.2);
  bench::Schedule gap(deg_to_rad(1.0));
  gap.add(0.3, deg_to_rad(1.0));
  gap.add(0.3, deg_to_rad(1.6));
  config.gap_program = gap;
  bench::PlantService service(config);
  const auto maps = test::source_path("drivers/configs");
  drv::ModbusDriveEmulator drive_emu(tcp(0), drv::RegisterMap::load(maps / "modbus_drive_map.yaml"), service.add_drive());
  drv::ModbusTransducerEmulator pg_emu(tcp(0), drv::RegisterMap::load(maps / "modbus_transducer_map.yaml"), service.transducer());
  service.start();
  drv::ModbusDrive drive({tcp(drive_emu.port()), drv::RegisterMap::load(maps / "modbus_drive_map.yaml"), 5000ms});
  drv::ModbusTransducer pg({tcp(pg_emu.port()), drv::RegisterMap::load(maps / "modbus_transducer_map.yaml")});
  drive.configure();
  pg.configure();
  drive.activate();
  ASSERT_TRUE(eventually([&] { return pg.read(bench::Clock::now(), 1ms).pressure_pa > 0; }));
  EXPECT_NEAR(pg.read(bench::Clock::now(), 1ms).pressure_pa, 1.2e6, 15e3);  // the noisy reading
  ASSERT_TRUE(eventually([&] { return service.sample().enabled; }));
  ASSERT_TRUE(eventually([&] { return std::abs(units::rad_to_deg(service.sample().gap_rad) - 1.6) < 1e-9; }, 5s));
  // Close the valve 3 deg: the pressure rises.
  const double start = drive.read(bench::Clock::now(), 1ms).position_rad;
  for (int i = 0; i < 600; ++i) {
    drive.write(bench::Clock::now(), 1ms, {start - deg_to_rad(3.0), true, false});
    std::this_thread::sleep_for(1ms);
  }
  ASSERT_TRUE(eventually([&] { return pg.read(bench::Clock::now(), 1ms).pressure_pa > 1.35e6; }, 5s));
}

}  // namespace
