// Motor drive in position mode: first-order lag on the command, then a slew-rate limit.
// With a measured encoder angle (replay), the measurement replaces the model.
#include <algorithm>
#include <cmath>

#include "hil/physics.hpp"
#include "hil/plant/registry.hpp"
#include "hil/units.hpp"

namespace hil::plant {

class MotorServo final : public ScalarEffect<MotorServo> {
 public:
  static constexpr std::string_view kKind = "motor_servo";
  static constexpr Stage kStage = Stage::motor;
  static constexpr ParamSpec kSpecs[] = {
      {"time_constant_s", 0, 10, true, false, kNaN, "first-order lag of the position servo"},
      {"rate_limit_deg_s", 1e-3, 1e6, false, false, kNaN, "slew-rate limit of the motor (a slower one would never move)"},
  };
  using ScalarEffect::ScalarEffect;

  // State: motor angle; then the lag's factor exp(-dt / tau) and the step it was computed for (the
  // step is the loop's period, so the exp runs once a run rather than once a step).
  std::size_t state_size() const noexcept override { return 3; }
  void settle(std::span<double> x, Signals& s) const override {
    x[0] = std::isfinite(s.theta_motor_meas_rad) ? s.theta_motor_meas_rad : s.theta_cmd_rad;
    x[1] = x[2] = 0;
    s.theta_motor_rad = x[0];
  }
  void step(std::span<double> x, Signals& s, double dt_s, Rng&) const noexcept override {
    if (std::isfinite(s.theta_motor_meas_rad)) {
      x[0] = s.theta_motor_meas_rad;
    } else {
      if (x[2] != dt_s || x[1] == 0) {  // 0: not computed yet (a keep of 0 is cheap to recompute)
        x[1] = physics::servo_keep(dt_s, value(0));
        x[2] = dt_s;
      }
      x[0] = physics::servo_step_rad(x[0], s.theta_cmd_rad, x[1], units::deg_to_rad(value(1)) * dt_s);
    }
    s.theta_motor_rad = x[0];
  }
};

HIL_REGISTER_EFFECT(MotorServo, "position servo: first-order lag and rate limit on the command")

}  // namespace hil::plant
