#include "hil/bench/rt/safety.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "hil/config.hpp"
#include "hil/units.hpp"

namespace hil::bench {

using units::deg_to_rad;
using units::kPaPerMpa;

std::string_view to_string(Trip trip) noexcept {
  switch (trip) {
    case Trip::none: return "none";
    case Trip::overpressure: return "overpressure";
    case Trip::underpressure: return "underpressure";
    case Trip::watchdog: return "watchdog";
    case Trip::rig_fault: return "rig fault";
    case Trip::overruns: return "overruns";
    case Trip::operator_abort: return "operator abort";
    case Trip::recording: return "recording";
    case Trip::following_error: return "following error";
  }
  return "?";
}

SafetyConfig SafetyConfig::none() noexcept {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  SafetyConfig c;
  c.cmd_min_rad = -kInf;
  c.cmd_max_rad = kInf;
  c.rate_limit_rad_s = kInf;
  c.p_max_pa = kInf;
  c.p_min_pa = -kInf;
  c.watchdog_misses = std::numeric_limits<int>::max();
  return c;
}

SafetyConfig SafetyConfig::from_yaml(const cfg::Node& n) {
  n.allow_keys({"cmd_min_deg", "cmd_max_deg", "rate_limit_deg_s", "p_max_mpa", "p_min_mpa", "pressure_debounce",
                "watchdog_misses", "safe_state", "safe_angle_deg", "safe_rate_deg_s", "safe_hold_ms", "following_error"});
  SafetyConfig c;
  c.cmd_min_rad = deg_to_rad(n.number("cmd_min_deg"));
  c.cmd_max_rad = deg_to_rad(n.number("cmd_max_deg"));
  n.at("cmd_max_deg").require(c.cmd_max_rad > c.cmd_min_rad, "must be above cmd_min_deg");
  c.rate_limit_rad_s = deg_to_rad(n.number("rate_limit_deg_s"));
  n.at("rate_limit_deg_s").require(c.rate_limit_rad_s > 0, "must be > 0");
  c.p_max_pa = n.number("p_max_mpa") * kPaPerMpa;
  c.p_min_pa = n.number("p_min_mpa") * kPaPerMpa;
  n.at("p_min_mpa").require(c.p_min_pa >= 0, "must be >= 0");
  n.at("p_max_mpa").require(c.p_max_pa > c.p_min_pa, "must be above p_min_mpa");
  // Checked before narrowing to int (a cast first took 'watchdog_misses: 4294967299' as 3).
  c.pressure_debounce = static_cast<int>(n.integer_in("pressure_debounce", 3, 1, 1'000'000, "readings in a row"));
  c.watchdog_misses = static_cast<int>(n.integer_in("watchdog_misses", 3, 1, 1'000'000, "missed reads in a row"));
  const std::string mode = n.text("safe_state", "hold");
  if (mode == "hold") {
    c.safe_mode = SafeMode::hold;
  } else if (mode == "angle") {
    c.safe_mode = SafeMode::angle;
    c.safe_angle_rad = deg_to_rad(n.number("safe_angle_deg"));
    n.at("safe_angle_deg")
        .require(c.safe_angle_rad >= c.cmd_min_rad && c.safe_angle_rad <= c.cmd_max_rad,
                 "must lie within cmd_min_deg..cmd_max_deg");
    c.safe_rate_rad_s = deg_to_rad(n.number("safe_rate_deg_s", 20));
    if (n.has("safe_rate_deg_s")) n.at("safe_rate_deg_s").require(c.safe_rate_rad_s > 0, "must be > 0");
  } else {
    n.at("safe_state").fail("must be 'hold' or 'angle', got '" + mode + "'");
  }
  c.safe_hold_s = n.number("safe_hold_ms", 200) / 1000.0;
  if (n.has("safe_hold_ms")) n.at("safe_hold_ms").require(c.safe_hold_s >= 0 && c.safe_hold_s <= 60, "must be 0..60000");
  if (n.has("following_error")) {
    const cfg::Node f = n.at("following_error");
    f.allow_keys({"max_deg", "time_ms"});
    const double max_deg = f.number("max_deg");
    f.at("max_deg").require(max_deg > 0 && max_deg <= 360, "must be above 0 and at most 360");
    c.following_error_rad = deg_to_rad(max_deg);
    f.at("time_ms");  // required: how long a normal lag may last is the rig's to say
    c.following_error_s =
        static_cast<double>(f.milliseconds_in("time_ms", std::chrono::milliseconds(0), 0, 60000).count()) / 1000.0;
  }
  return c;
}

Trip Safety::check(bool missed, bool rig_fault, double p_meas_pa, double& value, double& limit) noexcept {
  if (rig_fault) return Trip::rig_fault;
  if (missed) {
    value = ++misses_;
    limit = c_.watchdog_misses;
    return misses_ >= c_.watchdog_misses ? Trip::watchdog : Trip::none;
  }
  misses_ = 0;
  over_ = p_meas_pa > c_.p_max_pa ? over_ + 1 : 0;
  under_ = p_meas_pa < c_.p_min_pa ? under_ + 1 : 0;
  value = p_meas_pa;
  if (over_ >= c_.pressure_debounce) {
    limit = c_.p_max_pa;
    return Trip::overpressure;
  }
  if (under_ >= c_.pressure_debounce) {
    limit = c_.p_min_pa;
    return Trip::underpressure;
  }
  return Trip::none;
}

Trip Safety::follow(double target_rad, double position_rad, double dt_s, double& value, double& limit) noexcept {
  const double error = position_rad - target_rad;
  if (!std::isfinite(position_rad)) return Trip::none;
  beyond_s_ = std::abs(error) > c_.following_error_rad ? beyond_s_ + dt_s : 0;
  // Half a period of slack: a sum of periods lands a rounding error either side of the time.
  if (beyond_s_ == 0 || beyond_s_ + 0.5 * dt_s <= c_.following_error_s) return Trip::none;
  value = error;
  limit = c_.following_error_rad;
  return Trip::following_error;
}

double Safety::limit(double cmd_rad, double last_rad, double dt_s, bool& limited) const noexcept {
  if (!std::isfinite(cmd_rad)) {  // never pass a broken command on: hold
    limited = true;
    return last_rad;
  }
  double out = std::clamp(cmd_rad, c_.cmd_min_rad, c_.cmd_max_rad);
  const double step = c_.rate_limit_rad_s * dt_s;
  out = std::clamp(out, last_rad - step, last_rad + step);
  limited = out != cmd_rad;
  return out;
}

double Safety::safe_command(double last_rad, double dt_s) const noexcept {
  if (c_.safe_mode == SafeMode::hold) return last_rad;
  const double step = c_.safe_rate_rad_s * dt_s;
  return std::clamp(c_.safe_angle_rad, last_rad - step, last_rad + step);
}

}  // namespace hil::bench
