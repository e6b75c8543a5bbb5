// One period's record, as the loop fills it (RunLoop::cycle, the only place it is filled) and as
// it goes into telemetry.csv, the live telemetry and the reports: the columns of the one schema
// (hil/telemetry_schema.hpp), in one of three sets.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "hil/bench/campaign/run_metrics.hpp"
#include "hil/csv_writer.hpp"
#include "hil/telemetry_schema.hpp"

namespace hil::bench {

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
// The values for telemetry_columns(set), at the front of `out`; returns how many. Real-time safe.
std::size_t telemetry_row(const TelemetryRecord& r, ColumnSet set, TelemetryRow& out) noexcept;

}  // namespace hil::bench
