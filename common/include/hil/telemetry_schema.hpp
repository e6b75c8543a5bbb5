// The telemetry columns, written once: `hilbench sim` writes the first kSimColumns, the bench's
// recorder all of them (less the truth-only ones on a rig that cannot know the truth), the
// measurement reader and the reports read them by these names. The first five are the
// measurement format of physics.md section 4. A column's name carries its unit.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string_view>
#include <utility>

#include "hil/units.hpp"

namespace hil::telemetry {

enum class Col : std::uint8_t {
  t_s,
  theta_cmd_deg,
  p_meas_mpa,
  theta_motor_deg,
  p_ref_mpa,
  theta_valve_deg,
  gap_true_deg,
  touch_state,
  motion_intention,
  comp_deg,
  gap_est_deg,
  p_chamber_mpa,
  theta_target_deg,
  wake_latency_us,
  compute_us,
  loop_flags,
};

struct Column {
  std::string_view name;
  int decimals;     // fixed-point digits after the decimal point in telemetry.csv
  bool truth_only;  // only a simulated plant knows it (left out on CAN and Modbus rigs)
  std::string_view meaning;
};

inline constexpr std::array<Column, 16> kColumns = {{
    {"t_s", 4, false, "time since the run's start"},
    {"theta_cmd_deg", 5, false, "motor command the controller sent"},
    {"p_meas_mpa", 6, false, "chamber pressure as the transducer read it"},
    {"theta_motor_deg", 5, false, "motor angle (encoder)"},
    {"p_ref_mpa", 6, false, "pressure reference"},
    {"theta_valve_deg", 5, true, "valve angle behind the gear backlash"},
    {"gap_true_deg", 5, true, "the backlash gap the plant had"},
    {"touch_state", 0, false, "the observer's touch state Tf: -1 negative touch, 0 transition, +1 positive touch"},
    {"motion_intention", 0, false, "the observer's motion intention Mf: -1, 0, +1"},
    {"comp_deg", 5, false, "the compensator's jump delta_b applied this period"},
    {"gap_est_deg", 5, false, "the observer's gap estimate"},
    {"p_chamber_mpa", 6, true, "chamber pressure before the transducer"},
    {"theta_target_deg", 5, false, "what the drive was sent (the shaped command; the command when not shaped)"},
    {"wake_latency_us", 2, false, "how late the real-time thread woke for this period"},
    {"compute_us", 2, false, "the period's read-step-write time"},
    {"loop_flags", 0, false,
     "the period's flags (kFlag* in bench/include/hil/bench/rt/rt_loop.hpp): faults, read missed, command limited, safe state, "
     "overrun"},
}};

// hilbench sim writes t_s .. p_chamber_mpa; the bench's loop adds theta_target_deg .. loop_flags.
inline constexpr std::size_t kSimColumns = static_cast<std::size_t>(Col::p_chamber_mpa) + 1;
inline constexpr std::size_t kLoopColumns = kColumns.size();

constexpr std::size_t index(Col c) noexcept { return static_cast<std::size_t>(c); }
constexpr const Column& column(Col c) noexcept { return kColumns[index(c)]; }
constexpr std::string_view name(Col c) noexcept { return column(c).name; }

// A column's unit, read off its name's suffix (the names carry their units); "" for codes and flags.
constexpr std::string_view unit(Col c) noexcept {
  const std::string_view n = name(c);
  constexpr std::pair<std::string_view, std::string_view> kSuffixes[] = {
      {"_s", "s"}, {"_deg", "deg"}, {"_mpa", "MPa"}, {"_us", "us"}};
  for (const auto& [suffix, u] : kSuffixes)
    if (n.size() > suffix.size() && n.substr(n.size() - suffix.size()) == suffix) return u;
  return "";
}

// A column's value from the SI unit the code keeps it in (rad, Pa; s, us, codes and flags as they
// are) to the column's unit (deg, MPa), and back: the writer of a row, and every reader that turns
// a row back into values (the run report's record, the measurement reader), convert with these.
constexpr double from_si(Col c, double si) noexcept {
  const std::string_view u = unit(c);
  return u == "deg" ? units::rad_to_deg(si) : u == "MPa" ? units::pa_to_mpa(si) : si;
}
constexpr double to_si(Col c, double value) noexcept {
  const std::string_view u = unit(c);
  return u == "deg" ? units::deg_to_rad(value) : u == "MPa" ? units::mpa_to_pa(value) : value;
}

// The topic of the telemetry (every column of a row in one message) in the live Foxglove stream
// and in telemetry.mcap; the readers of a run's MCAP look for it.
inline constexpr std::string_view kTopic = "/hilbench/telemetry";

}  // namespace hil::telemetry
