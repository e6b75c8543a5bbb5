// TEST DOUBLES for the drivers' parts (hil/drv/parts.hpp): a position drive that goes where it is
// told at once and a pressure sensor that reads what the test sets, both on the test's thread
// with no I/O thread, so a rig composed of them can be checked period by period. Each can fall
// silent or report a fault on purpose.
#pragma once

#include <chrono>
#include <string_view>

#include "hil/drv/parts.hpp"

namespace hil::test {

class TestPositionDrive final : public drv::PositionDrive {
 public:
  explicit TestPositionDrive(drv::FeedbackFreshness freshness = drv::FeedbackFreshness::polled, double start_rad = 0.0)
      : freshness_(freshness), start_rad_(start_rad) {}

  void configure() override {
    ++configures;
    feedback_ = {};
    feedback_.position_rad = start_rad_;
    feedback_.velocity_rad_s = 0.0;
    reply();
    health_.connected = true;
  }
  void activate() override {
    ++activations;
    feedback_.enabled = true;
    reply();
  }
  void deactivate() override {
    ++deactivations;
    feedback_.enabled = false;
    reply();
  }

  // Real-time safe.
  drv::DriveFeedback read(drv::Clock::time_point, drv::Clock::duration) noexcept override { return feedback_; }
  // Real-time safe: the drive is at the target at once and answers (unless silent).
  void write(drv::Clock::time_point, drv::Clock::duration, const drv::DriveCommand& command) noexcept override {
    ++writes;
    last_command = command;
    if (silent_) return;
    feedback_.position_rad = command.target_position_rad;
    reply();
  }
  drv::DeviceHealth health() const noexcept override { return health_; }
  drv::FeedbackFreshness freshness() const noexcept override { return freshness_; }
  std::string_view missing_reply_text() const noexcept override { return "no test reply since the last write"; }

  // Test hooks.
  void set_silent(bool on) noexcept { silent_ = on; }
  // A polled drive's next poll: the feedback is new as of now.
  void poll() noexcept { reply(); }
  void raise_fault(std::string_view text) noexcept {
    feedback_.fault = true;
    feedback_.enabled = false;
    health_.fault = true;
    health_.set_last_error(text);
  }

  int configures = 0, activations = 0, deactivations = 0;
  long writes = 0;
  drv::DriveCommand last_command{};

 private:
  void reply() noexcept {
    feedback_.valid = true;
    feedback_.rx_time = drv::Clock::now();
    ++feedback_.sequence;
    health_.last_heartbeat = feedback_.rx_time;
  }

  const drv::FeedbackFreshness freshness_;
  const double start_rad_;
  drv::DriveFeedback feedback_{};
  drv::DeviceHealth health_{};
  bool silent_ = false;
};

class TestPressureSensor final : public drv::PressureSensor {
 public:
  explicit TestPressureSensor(double pressure_pa = 1.0e6) : pressure_pa_(pressure_pa) {}

  void configure() override {
    ++configures;
    set_pressure(pressure_pa_);
    health_.connected = true;
  }
  // Real-time safe.
  drv::PressureReading read(drv::Clock::time_point, drv::Clock::duration) noexcept override { return reading_; }
  drv::DeviceHealth health() const noexcept override { return health_; }

  // Test hooks: a new reading, received now.
  void set_pressure(double pressure_pa) noexcept {
    pressure_pa_ = pressure_pa;
    reading_.pressure_pa = pressure_pa;
    reading_.valid = true;
    reading_.rx_time = drv::Clock::now();
    ++reading_.sequence;
  }
  void raise_fault(std::string_view text) noexcept {
    reading_.fault = true;
    health_.fault = true;
    health_.set_last_error(text);
  }

  int configures = 0;

 private:
  double pressure_pa_;
  drv::PressureReading reading_{};
  drv::DeviceHealth health_{};
};

}  // namespace hil::test
