// Motor drive in position mode: first-order lag on the command, then a slew-rate limit.
// With a measured encoder angle (replay), the measurement replaces the model.
#include <algorithm>
#include <cmath>

#include "hil/physics.hpp"
#include "hil/plant/fit_prior.hpp"
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

  // How diagnose finds a servo other than the model's (fit_prior.hpp; candidate motor_dynamics,
  // refitting this block): a lag, a rate limit, or both. A rate limit's cost is flat until it
  // binds, so besides fractions of the model's limit it starts from what the file's command asks
  // of the drive (its 95th-percentile rate): a limit of 60/30/15 deg/s never bound on a run whose
  // command moved at 10 deg/s, and a 4 deg gap stepping by 3 deg stood in for the slow drive.
  static FitPrior fit_prior(const FitEvidence& ev) {
    const double tau = ev.model_value("motor_servo", "time_constant_s");
    const double rate = ev.model_value("motor_servo", "rate_limit_deg_s");
    std::vector<double> rate_starts = {rate, 0.5 * rate, 0.25 * rate};
    if (const double asked = ev.command_rate_deg_s; std::isfinite(asked) && asked > 1 && asked < 0.25 * rate) {
      for (double f : {0.8, 0.5, 0.3}) rate_starts.push_back(f * asked);
    }
    FitPrior p;
    p.candidate = "motor_dynamics";
    p.description = "the servo's lag or rate limit differs from the model's (refits motor_servo)";
    p.refit = true;
    p.command_side = true;
    p.params = {
        {.key = "time_constant_s", .lo = 1e-4, .hi = 0.5, .scale = 0.002, .starts = {tau, 3 * tau, 8 * tau}, .sample_step = true},
        {.key = "rate_limit_deg_s", .lo = 1, .hi = 1000, .scale = 1, .starts = rate_starts}};
    p.variants = {{"lag", {"time_constant_s"}},
                  {"rate limit", {"rate_limit_deg_s"}},
                  {"lag and rate limit", {"time_constant_s", "rate_limit_deg_s"}}};
    return p;
  }

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
HIL_REGISTER_FIT_PRIOR(MotorServo)

}  // namespace hil::plant
