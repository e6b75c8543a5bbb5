#include "hil/bench/rt/telemetry_record.hpp"

#include <cmath>

#include "hil/units.hpp"

namespace hil::bench {

namespace {

bool in_set(std::size_t column, ColumnSet set) noexcept {
  switch (set) {
    case ColumnSet::sim: return column < telemetry::kSimColumns;
    case ColumnSet::all: return true;
    case ColumnSet::measured: return !telemetry::kColumns[column].truth_only;
  }
  return false;
}

}  // namespace

const std::vector<CsvColumn>& telemetry_columns(ColumnSet set) {
  static const auto make = [](ColumnSet s) {
    std::vector<CsvColumn> c;
    for (std::size_t i = 0; i < telemetry::kColumns.size(); ++i)
      if (in_set(i, s)) c.push_back({std::string(telemetry::kColumns[i].name), telemetry::kColumns[i].decimals});
    return c;
  };
  static const std::vector<CsvColumn> sim = make(ColumnSet::sim), all = make(ColumnSet::all),
                                      measured = make(ColumnSet::measured);
  switch (set) {
    case ColumnSet::sim: return sim;
    case ColumnSet::all: return all;
    case ColumnSet::measured: break;
  }
  return measured;
}

TelemetryRow telemetry_row(const TelemetryRecord& rec) noexcept {
  using telemetry::Col;
  using units::pa_to_mpa;
  using units::rad_to_deg;
  const StepRecord& r = rec.step;
  TelemetryRow row{};
  auto set = [&row](Col c, double v) { row[telemetry::index(c)] = v; };
  set(Col::t_s, r.t_s);
  set(Col::theta_cmd_deg, rad_to_deg(r.theta_cmd_rad));
  set(Col::p_meas_mpa, pa_to_mpa(r.p_meas_pa));
  set(Col::theta_motor_deg, rad_to_deg(r.theta_motor_rad));
  set(Col::p_ref_mpa, pa_to_mpa(r.p_ref_pa));
  set(Col::theta_valve_deg, rad_to_deg(r.theta_valve_rad));
  set(Col::gap_true_deg, rad_to_deg(r.gap_true_rad));
  set(Col::touch_state, static_cast<double>(r.touch));
  set(Col::motion_intention, static_cast<double>(r.intention));
  set(Col::comp_deg, rad_to_deg(r.comp_rad));
  set(Col::gap_est_deg, rad_to_deg(r.gap_est_rad));
  set(Col::p_chamber_mpa, pa_to_mpa(r.p_chamber_pa));
  set(Col::theta_target_deg, rad_to_deg(std::isfinite(rec.theta_target_rad) ? rec.theta_target_rad : r.theta_cmd_rad));
  set(Col::wake_latency_us, rec.wake_latency_us);
  set(Col::compute_us, rec.compute_us);
  set(Col::loop_flags, static_cast<double>(rec.flags));
  return row;
}

std::size_t telemetry_row(const TelemetryRecord& r, ColumnSet set, TelemetryRow& out) noexcept {
  const TelemetryRow all = telemetry_row(r);
  std::size_t n = 0;
  for (std::size_t i = 0; i < all.size(); ++i)
    if (in_set(i, set)) out[n++] = all[i];
  return n;
}

}  // namespace hil::bench
