// TEST DOUBLES for the emulators (models.hpp): a first-order position servo and a pressure that
// is a plain function of that servo's position. Good enough to see a drive follow a target and a
// transducer change; not the plant (that lives in plant_rt/).
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <mutex>

#include "hil/drv/models.hpp"
#include "hil/physics.hpp"

namespace hil::drv {

class FirstOrderServoTestModel final : public DriveModel {
 public:
  explicit FirstOrderServoTestModel(double tau_s = 0.01, double rate_limit_rad_s = 10.0, double start_rad = 0.0)
      : tau_s_(tau_s), rate_limit_rad_s_(rate_limit_rad_s), position_rad_(start_rad), target_rad_(start_rad) {}

  void command(double target_position_rad, bool enabled) override {
    std::lock_guard lock(mutex_);
    advance();
    target_rad_ = target_position_rad;
    enabled_ = enabled;
  }
  DriveModelSample sample() override {
    std::lock_guard lock(mutex_);
    advance();
    return {position_rad_, velocity_rad_s_, fault_code_ != 0, fault_code_};
  }
  void reset_fault() override {
    std::lock_guard lock(mutex_);
    fault_code_ = 0;
  }
  // Test hook: the drive trips by itself (0 clears).
  void inject_fault(std::uint16_t code) {
    std::lock_guard lock(mutex_);
    fault_code_ = code;
  }
  double target_rad() {
    std::lock_guard lock(mutex_);
    return target_rad_;
  }
  bool enabled() {
    std::lock_guard lock(mutex_);
    return enabled_;
  }

 private:
  void advance() {
    const auto now = std::chrono::steady_clock::now();
    const double dt = std::chrono::duration<double>(now - last_).count();
    last_ = now;
    if (!enabled_ || fault_code_ != 0 || dt <= 0) {
      velocity_rad_s_ = 0;
      return;
    }
    const double before = position_rad_;
    position_rad_ = physics::servo_step_rad(position_rad_, target_rad_, physics::servo_keep(dt, tau_s_), rate_limit_rad_s_ * dt);
    velocity_rad_s_ = (position_rad_ - before) / dt;
  }

  std::mutex mutex_;
  double tau_s_, rate_limit_rad_s_;
  double position_rad_, target_rad_;
  double velocity_rad_s_ = 0;
  bool enabled_ = false;
  std::uint16_t fault_code_ = 0;
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

// p = p0 - slope * position: opening the valve lowers the pressure.
class PositionPressureTestModel final : public PressureModel {
 public:
  PositionPressureTestModel(DriveModel& drive, double p0_pa, double slope_pa_per_rad)
      : drive_(&drive), p0_pa_(p0_pa), slope_pa_per_rad_(slope_pa_per_rad) {}
  // Without a drive: a constant pressure, settable.
  explicit PositionPressureTestModel(double p0_pa) : p0_pa_(p0_pa) {}

  double pressure_pa() override {
    std::lock_guard lock(mutex_);
    return p0_pa_ - (drive_ ? slope_pa_per_rad_ * drive_->sample().position_rad : 0.0);
  }
  bool sensor_fault() override {
    std::lock_guard lock(mutex_);
    return fault_;
  }
  void set_p0_pa(double p) {
    std::lock_guard lock(mutex_);
    p0_pa_ = p;
  }
  void set_sensor_fault(bool f) {
    std::lock_guard lock(mutex_);
    fault_ = f;
  }

 private:
  std::mutex mutex_;
  DriveModel* drive_ = nullptr;
  double p0_pa_;
  double slope_pa_per_rad_ = 0;
  bool fault_ = false;
};

}  // namespace hil::drv
