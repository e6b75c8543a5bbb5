// What the device emulators are backed by. The bench wires the real plant model behind these;
// tests use the doubles in tests/support/servo_test_model.hpp. Implementations must be thread-safe: an
// emulator calls them from its own thread while the plant may advance from another. They own
// time: an emulator never tells them how much time passed.
#pragma once

#include <cstdint>

namespace hil::drv {

struct DriveModelSample {
  double position_rad = 0.0;  // load-side (valve) angle, as the drive's encoder reports it
  double velocity_rad_s = 0.0;
  bool fault = false;            // the drive's own fault (over-current, following error...)
  std::uint16_t fault_code = 0;  // CiA 402 / EMCY error code when fault, e.g. 0x2310
};

class DriveModel {
 public:
  virtual ~DriveModel() = default;
  // The newest target and whether the power stage follows it.
  virtual void command(double target_position_rad, bool enabled) = 0;
  virtual DriveModelSample sample() = 0;
  // A fault reset from the drive's controlword; the model clears its fault if it can.
  virtual void reset_fault() {}
};

class PressureModel {
 public:
  virtual ~PressureModel() = default;
  virtual double pressure_pa() = 0;
  virtual bool sensor_fault() { return false; }
};

}  // namespace hil::drv
