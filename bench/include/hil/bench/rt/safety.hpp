// Safety interlocks between the controller and the rig: command angle and rate limits, pressure
// abort thresholds, the watchdog on rig reads, and what the safe state commands. Pure: the loop
// owns the state and the clock; every method used on the loop is real-time safe.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <string_view>

namespace hil::cfg {
class Node;
}

namespace hil::bench {

enum class SafeMode : std::uint8_t {
  hold,   // keep commanding the last command sent
  angle,  // drive to safe_angle_rad at safe_rate_rad_s
};

struct SafetyConfig {
  double cmd_min_rad = -0.0873;  // command angle limits (clamped, not a trip)
  double cmd_max_rad = 0.6109;
  double rate_limit_rad_s = 87.3;  // largest command change per second (clamped)
  double p_max_pa = 2.5e6;         // overpressure abort
  double p_min_pa = 0.2e6;         // underpressure abort
  int pressure_debounce = 3;       // consecutive readings beyond a threshold before it trips
  int watchdog_misses = 3;         // consecutive missed rig reads before it trips
  SafeMode safe_mode = SafeMode::hold;
  double safe_angle_rad = 0;
  double safe_rate_rad_s = 0.349;  // how fast the safe state drives there (20 deg/s)
  double safe_hold_s = 0.2;        // the loop stays in the safe state this long, then the run ends
  // Following error: the drive's reported position more than following_error_rad from the target
  // it was sent the period before, for following_error_s in a row (a frozen encoder, a jammed
  // gear, a drive that stopped following). Off (infinite) unless the rig file sets it: what is a
  // normal lag depends on the drive and on the rig's target shaping.
  double following_error_rad = std::numeric_limits<double>::infinity();
  double following_error_s = 0;
  bool watches_following() const noexcept { return std::isfinite(following_error_rad); }

  // No interlocks: no limits, no trips. An offline simulation has no motor to protect and records
  // what the controller does, whatever it does (a runaway estimate included).
  static SafetyConfig none() noexcept;
  // The `safety` block of a rig file; errors name file:line:key.
  static SafetyConfig from_yaml(const cfg::Node& node);
};

// recording: telemetry could not be recorded (a write error, a full disk, a full ring), and the
// rig's loop.recording_fault policy says a run without its record must not go on.
enum class Trip : std::uint8_t {
  none,
  overpressure,
  underpressure,
  watchdog,
  rig_fault,
  overruns,
  operator_abort,
  recording,
  following_error
};
std::string_view to_string(Trip trip) noexcept;

// The interlocks' memory between periods. One per run, used by the loop thread only.
class Safety {
 public:
  explicit Safety(const SafetyConfig& config) noexcept : c_(config) {}
  const SafetyConfig& config() const noexcept { return c_; }

  // One period's reading. `missed`: the rig gave no usable reading. Returns the first trip the
  // reading causes, and in `value` / `limit` what was measured and what it crossed.
  // Real-time safe.
  Trip check(bool missed, bool rig_fault, double p_meas_pa, double& value, double& limit) noexcept;
  int misses_in_a_row() const noexcept { return misses_; }
  // One period's following error: the drive's position against the target sent the period
  // before (the reading answers that target), `dt_s` the loop period. Returns
  // Trip::following_error once it has been beyond the limit for following_error_s in a row, with
  // the error in `value` and the limit in `limit` (rad). A non-finite position (the rig measures
  // none) is not checked. Real-time safe.
  Trip follow(double target_rad, double position_rad, double dt_s, double& value, double& limit) noexcept;

  // Clamps a command to the angle limits, then to the rate limit from the last command sent.
  // Sets `limited` when either changed it. Real-time safe.
  double limit(double cmd_rad, double last_rad, double dt_s, bool& limited) const noexcept;
  // The safe state's command this period, from the last command sent. Real-time safe.
  double safe_command(double last_rad, double dt_s) const noexcept;

 private:
  SafetyConfig c_;
  int misses_ = 0;
  int over_ = 0, under_ = 0;
  double beyond_s_ = 0;  // how long the following error has been beyond the limit
};

}  // namespace hil::bench
