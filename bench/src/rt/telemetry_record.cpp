#include "hil/bench/rt/telemetry_record.hpp"

#include <cmath>
#include <type_traits>

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

// The one table of a record's fields: each column of the schema and the member that holds it (in
// SI; the column's unit is its name's, telemetry::from_si/to_si convert). The writer
// (telemetry_row) and the reader (set_field: the run report) both walk it, so a column is added
// or moved here alone. A compile-time list, so that the writer, called for every row of a
// simulation, stays a straight sequence of stores.
template <telemetry::Col C>
using Column = std::integral_constant<telemetry::Col, C>;

template <typename F>
void for_each_field(F&& f) {
  using telemetry::Col;
  f(
      Column<Col::t_s>{}, [](auto& r) -> auto& { return r.step.t_s; });
  f(
      Column<Col::theta_cmd_deg>{}, [](auto& r) -> auto& { return r.step.theta_cmd_rad; });
  f(
      Column<Col::p_meas_mpa>{}, [](auto& r) -> auto& { return r.step.p_meas_pa; });
  f(
      Column<Col::theta_motor_deg>{}, [](auto& r) -> auto& { return r.step.theta_motor_rad; });
  f(
      Column<Col::p_ref_mpa>{}, [](auto& r) -> auto& { return r.step.p_ref_pa; });
  f(
      Column<Col::theta_valve_deg>{}, [](auto& r) -> auto& { return r.step.theta_valve_rad; });
  f(
      Column<Col::gap_true_deg>{}, [](auto& r) -> auto& { return r.step.gap_true_rad; });
  f(
      Column<Col::touch_state>{}, [](auto& r) -> auto& { return r.step.touch; });
  f(
      Column<Col::motion_intention>{}, [](auto& r) -> auto& { return r.step.intention; });
  f(
      Column<Col::comp_deg>{}, [](auto& r) -> auto& { return r.step.comp_rad; });
  f(
      Column<Col::gap_est_deg>{}, [](auto& r) -> auto& { return r.step.gap_est_rad; });
  f(
      Column<Col::p_chamber_mpa>{}, [](auto& r) -> auto& { return r.step.p_chamber_pa; });
  f(
      Column<Col::theta_target_deg>{}, [](auto& r) -> auto& { return r.theta_target_rad; });
  f(
      Column<Col::wake_latency_us>{}, [](auto& r) -> auto& { return r.wake_latency_us; });
  f(
      Column<Col::compute_us>{}, [](auto& r) -> auto& { return r.compute_us; });
  f(
      Column<Col::loop_flags>{}, [](auto& r) -> auto& { return r.flags; });
  static_assert(telemetry::kColumns.size() == 16, "a column was added to the schema: add its field above");
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
  TelemetryRow row{};
  for_each_field([&](auto column, auto member) {
    constexpr telemetry::Col c = decltype(column)::value;
    double si = static_cast<double>(member(rec));
    // Where the rig was sent no shaped target, the target is the command (never a NaN column).
    if constexpr (c == telemetry::Col::theta_target_deg)
      if (!std::isfinite(si)) si = rec.step.theta_cmd_rad;
    row[telemetry::index(c)] = telemetry::from_si(c, si);
  });
  return row;
}

void set_field(TelemetryRecord& rec, telemetry::Col c, double value) noexcept {
  for_each_field([&](auto column, auto member) {
    constexpr telemetry::Col col = decltype(column)::value;
    if (col == c) {
      auto& field = member(rec);
      field = static_cast<std::remove_reference_t<decltype(field)>>(telemetry::to_si(col, value));
    }
  });
}

std::size_t telemetry_row(const TelemetryRecord& r, ColumnSet set, TelemetryRow& out) noexcept {
  const TelemetryRow all = telemetry_row(r);
  std::size_t n = 0;
  for (std::size_t i = 0; i < all.size(); ++i)
    if (in_set(i, set)) out[n++] = all[i];
  return n;
}

}  // namespace hil::bench
