// What a recorded run's own record says about its telemetry (events.jsonl and run.json beside
// telemetry.csv), as compare and diagnose use it: the rows the measurement does not stand for (a
// sensor or drive fault the operator injected, a trip and the safe state after it) are left out
// of the fit and counted, and the gap changes the operator injected are known inputs of the
// replay (the plant's gap as recorded), not effects to find. The events are read as the reports
// mark them (report::marks_from_events): one reading of a run's events. Offline code: allocates.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "hil/report/run_marks.hpp"

namespace hil::analysis {

struct LeftOutWindow {
  double t0_s = 0, t1_s = 0;  // rows with t0 <= t < t1 (t1 may be +inf: to the end of the run)
  std::string why;            // "sensor stuck 1.52 MPa (operator)"
  // The rows of a measurement in it (counted by RunInputs::leave_out): data rows, 0-based.
  std::size_t first_row = 0, last_row = 0, rows = 0;
};

struct GapInput {
  double t_s = 0;
  double gap_rad = 0;  // from t_s on; NaN: the model's own gap again (the operator's "programme")
  std::string source;
};

struct RunInputs {
  std::vector<LeftOutWindow> left_out;  // in time order; they may overlap
  std::vector<GapInput> gap;            // in time order
  std::string unreadable;               // events.jsonl lines skipped (report::RunMarks::unreadable)
  bool empty() const { return left_out.empty() && gap.empty(); }
  // Whether the row at t (data row `row`, rows in time order) is left out; counts it in each
  // window that holds it.
  bool leave_out(std::size_t row, double t_s);
  // The gap input in force at t (NaN: none, the model's own).
  double gap_at(double t_s) const;
  // What was left out and what was fed in, in words: "rows 5918-18000 (5.917-18 s) left out:
  // sensor stuck 1.52 MPa (operator)", "gap 3.7 deg from 4.2 s: a known input of the replay
  // (operator)", and "12083 of 30000 rows left out" when any were. After the rows were counted.
  std::vector<std::string> notes(std::size_t total_rows) const;
  std::size_t rows_left_out() const { return rows_left_out_; }
  void left_out_counts_reset();  // to count the rows again (another pass over the same file)

 private:
  std::size_t rows_left_out_ = 0;
};

// From a run's marks: each sensor or drive fault's window, and from a trip or the safe state to
// the end; every gap change of the operator (a programmed one is the campaign's, which the model
// holds or a candidate finds).
RunInputs run_inputs_from(const report::RunMarks& marks);
// The run whose telemetry `data_file` is: events.jsonl in its folder, and run.json's trip when the
// events lack it. None for a measurement outside a run folder.
RunInputs run_inputs_beside(const std::filesystem::path& data_file);

}  // namespace hil::analysis
