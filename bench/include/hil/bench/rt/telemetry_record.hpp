// One period's record, as the loop fills it (RunLoop::cycle, the only place it is filled) and as
// it goes into telemetry.csv, the live telemetry and the reports: the columns of the one schema
// (hil/telemetry_schema.hpp), in one of three sets.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "hil/csv_writer.hpp"
#include "hil/telemetry_schema.hpp"

namespace hil::bench {

// One control period as the controller and the plant saw it, SI (the run metrics add these up).
struct StepRecord {
  double t_s = 0;
  double p_ref_pa = 0;
  double p_chamber_pa = 0;
  double p_meas_pa = 0;
  double theta_cmd_rad = 0;
  double theta_motor_rad = 0;
  double theta_valve_rad = 0;
  double gap_true_rad = 0;
  double gap_est_rad = 0;
  double comp_rad = 0;
  int touch = 0;
  int intention = 0;
  bool gap_measured = false;
};

struct TelemetryRecord {
  StepRecord step;
  double theta_target_rad = std::numeric_limits<double>::quiet_NaN();  // what the rig was sent; NaN: the command
  double wake_latency_us = 0;
  double compute_us = 0;
  std::uint32_t flags = 0;  // LoopFlag bits (rt_loop.hpp)
};

// Which columns a telemetry file has:
//   sim       `hilbench sim`: t_s .. p_chamber_mpa (telemetry::kSimColumns); no drive, no clock
//   all       the bench on a rig that knows the truth (simulated, hybrid): every column
//   measured  the bench on a CAN or Modbus rig: every column but the truth-only ones (rather
//             than columns of nan)
enum class ColumnSet : std::uint8_t { sim, all, measured };

using TelemetryRow = std::array<double, telemetry::kLoopColumns>;  // room for every column

const std::vector<CsvColumn>& telemetry_columns(ColumnSet set);
// Every column of the schema for one record, in schema order (units converted: deg, MPa).
// Real-time safe.
TelemetryRow telemetry_row(const TelemetryRecord& r) noexcept;
// The inverse of telemetry_row for one column: sets the record's field of column c from a value
// in the column's unit (the run report reads a recorded row back into a record with it).
void set_field(TelemetryRecord& r, telemetry::Col c, double value) noexcept;
// The values for telemetry_columns(set), at the front of `out`; returns how many. Real-time safe.
std::size_t telemetry_row(const TelemetryRecord& r, ColumnSet set, TelemetryRow& out) noexcept;

}  // namespace hil::bench
