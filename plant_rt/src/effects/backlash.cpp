// Backlash as the paper's hysteresis model, eq. (1) with m = 1: the valve follows the motor
// only while one flank of the gap pushes it, and holds otherwise (large load and damping).
// The valve stops clamp its travel. A gap program (campaign, operator, backlash_change) may
// set s.gap_rad before this stage; otherwise the configured gap applies.
#include <algorithm>
#include <cmath>

#include "hil/config.hpp"
#include "hil/physics.hpp"
#include "hil/plant/registry.hpp"
#include "hil/units.hpp"

namespace hil::plant {

class Backlash final : public ScalarEffect<Backlash> {
 public:
  static constexpr std::string_view kKind = "backlash";
  static constexpr Stage kStage = Stage::transmission;
  static constexpr ParamSpec kSpecs[] = {
      {"gap_deg", 0, 90, false, false, kNaN, "backlash size sigma (a gap cannot be negative)"},
      {"valve_min_deg", -360, 360, false, false, 0.0, "valve stop, closed end"},
      {"valve_max_deg", -360, 360, false, false, 30.0, "valve stop, open end"},
  };
  explicit Backlash(std::vector<double> v) : ScalarEffect(std::move(v)) {
    if (!(value(1) < value(2))) throw std::invalid_argument("backlash: valve_min_deg must be below valve_max_deg");
  }
  static std::shared_ptr<const Effect> from_yaml(const cfg::Node& block) {
    auto v = read_params(block, kSpecs);
    if (!(v[1] < v[2])) block.at("valve_max_deg").fail("must be above valve_min_deg");
    return std::make_shared<Backlash>(std::move(v));
  }

  std::size_t state_size() const noexcept override { return 1; }
  void settle(std::span<double> x, Signals& s) const override {
    const double half = gap(s) / 2;
    const double hint = std::isfinite(s.theta_valve_rad) ? s.theta_valve_rad : s.theta_motor_rad - half;
    x[0] = clamp_stops(std::clamp(hint, s.theta_motor_rad - half, s.theta_motor_rad + half));
    write(x[0], s);
  }
  void step(std::span<double> x, Signals& s, double, Rng&) const noexcept override {
    const double half = gap(s) / 2;
    x[0] = clamp_stops(physics::play_rad(x[0], s.theta_motor_rad, half));
    write(x[0], s);
  }

 private:
  double gap(Signals& s) const noexcept {
    if (!std::isfinite(s.gap_rad)) s.gap_rad = units::deg_to_rad(value(0));
    s.gap_rad = std::max(s.gap_rad, 0.0);
    return s.gap_rad;
  }
  double clamp_stops(double v) const noexcept { return std::clamp(v, units::deg_to_rad(value(1)), units::deg_to_rad(value(2))); }
  static void write(double valve_rad, Signals& s) noexcept {
    s.theta_valve_rad = valve_rad;
    s.theta_throat_rad = valve_rad;
  }
};

HIL_REGISTER_EFFECT(Backlash, "gear backlash, hysteresis model of the paper's eq. (1)")

}  // namespace hil::plant
