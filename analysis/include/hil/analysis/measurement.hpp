// Measurement files (physics.md section 4): t_s, theta_cmd_deg, p_meas_mpa required; the motor
// encoder theta_motor_deg and the reference p_ref_mpa optional; any other column is ignored.
// Read through hil::TableReader (a CSV, or a run's telemetry.mcap: the same rows from its
// telemetry topic), so a missing column, a non-numeric cell or time going backwards is a CsvError
// naming file:line:column (in an MCAP: the record's byte offset). Values are converted to SI here, once, and checked
// against what a log of this rig can hold (MeasurementLimits), so that nonsense is refused by
// file:line:column here instead of producing an overflow, a NaN metric or a hang further on.
// Setup/offline code: allocates and throws.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "hil/analysis/run_inputs.hpp"
#include "hil/table_reader.hpp"

namespace hil::analysis {

// Rows of a measurement in SI. theta_motor_rad / p_ref_pa are empty when the file lacks them.
struct MeasurementRows {
  std::vector<double> t_s, theta_cmd_rad, p_meas_pa, theta_motor_rad, p_ref_pa;
  std::vector<std::size_t> restarts;  // rows where a new acquisition starts (its time restarted)
  std::size_t size() const { return t_s.size(); }
  void clear();
  void append(const MeasurementRows& other);
  // Room for `rows` rows in each column `other` has (the optional ones may be absent).
  void reserve_like(const MeasurementRows& other, std::size_t rows);
};

// What a measurement file must satisfy beyond being numeric and in time order. Every bound is a
// physical statement about the rig, not a tuning knob:
//  - time: a gap between two rows of at most kMaxGapS (the replay crosses a gap open loop, the
//    inputs interpolated; longer than that it is two runs, not a dropout), and on average at least one row
//    per kMaxMeanPeriodS from the first row to any row k: t(k) - t(0) <= kMaxGapS + k kMaxMeanPeriodS
//    (the chamber's ~0.1 s dynamics must be sampled; this also bounds the replay's work at about
//    two plant steps per row, whatever the time stamps say);
//  - pressure within [kMinPressureMpa, kMaxPressureMpa] (a gauge reading a little below zero is an
//    offset; above 100 MPa it is not this chamber), and not constant over the file (a reading that
//    never moves carries no dynamics: a disconnected or saturated channel);
//  - angles (command, encoder) within +-kMaxAngleDeg: the valve travels 0-30 deg.
struct MeasurementLimits {
  static constexpr double kMaxGapS = 5.0;
  static constexpr double kMaxMeanPeriodS = 0.02;
  static constexpr double kMinPressureMpa = -1.0, kMaxPressureMpa = 100.0;
  static constexpr double kMinPressureSpreadPa = 1.0;  // max - min below this: constant
  static constexpr double kMaxAngleDeg = 360.0;
};

// Streams a measurement file in chunks (bounded memory for hour-long files). Each row is checked
// against MeasurementLimits as it is read; the whole-file checks (a constant pressure) run when
// next() reaches the end of a file of at least kMinRows rows.
class MeasurementReader {
 public:
  // dialect: the logger's CSV (csv_reader.hpp: separator, decimal mark, --columns; detected when
  // unset). acquisitions: time may restart (acquisitions appended to one file, MeasurementRows::
  // restarts); otherwise a restart is refused as time going backwards.
  explicit MeasurementReader(const std::filesystem::path& file, const CsvDialect& dialect = {}, bool acquisitions = false);
  bool has_encoder() const { return has_encoder_; }
  bool has_reference() const { return has_reference_; }
  const CsvHeader& header() const { return reader_.header(); }
  const std::filesystem::path& file() const { return file_; }
  // Next chunk of up to max_rows rows; false at the end. first_line: file line of the chunk's row 0.
  bool next(MeasurementRows& rows, std::size_t max_rows = 65536);
  std::size_t first_line() const { return first_line_; }  // of the last chunk
  std::size_t rows_read() const { return rows_read_; }
  std::size_t first_data_line() const { return first_data_line_; }  // file line of row 0
  double progress() const;                                          // fraction of the file's bytes consumed

 private:
  std::filesystem::path file_;
  TableReader reader_;
  CsvChunk chunk_;
  bool has_encoder_ = false, has_reference_ = false;
  std::size_t first_line_ = 0, rows_read_ = 0, first_data_line_ = 0;
  // Running state of the checks.
  double t_first_s_ = 0, t_last_s_ = 0;
  std::size_t acquisition_row_ = 0;  // file row of the current acquisition's first row
  double p_min_pa_ = 0, p_max_pa_ = 0;
  std::size_t last_data_line_ = 0;
  void check_rows(const CsvChunk& chunk);
  void check_whole_file() const;
  [[noreturn]] void fail_at(std::size_t line, std::string_view column, const std::string& what) const;
};

// A whole measurement in memory (diagnose, tests).
struct Measurement {
  std::filesystem::path file;
  MeasurementRows rows;
  bool has_encoder = false, has_reference = false;
  std::size_t first_data_line = 0;  // file line of row 0, for messages
  std::size_t acquisition = 0;      // of several appended in one file: 1, 2, ... (0: the file holds one)
  std::vector<std::pair<std::string, std::string>> metadata;
  // A recorded run's own record (run_inputs.hpp): the rows left out (counted) and the gap inputs.
  RunInputs run;
  // Per row: left out of the fit (empty: none is).
  std::vector<std::uint8_t> left_out;
  std::size_t scored_rows() const { return rows.size() - run.rows_left_out(); }
};

// Minimum rows for compare and diagnose (a fit needs a settle window and some dynamics).
inline constexpr std::size_t kMinRows = 50;

// Loads the whole file; throws CsvError (file:line:column) for bad content and for a file with
// fewer than kMinRows data rows ("too short to fit"). The telemetry of a recorded run comes with
// its run's record (run_inputs_beside), its left-out rows marked.
Measurement load_measurement(const std::filesystem::path& file, const CsvDialect& dialect = {});
// A file of one or more acquisitions appended (time restarting at or below the first row's): one
// Measurement each, in file order, to be diagnosed as files of one rig. Each needs kMinRows rows.
std::vector<Measurement> load_acquisitions(const std::filesystem::path& file, const CsvDialect& dialect = {});

// What a report calls a measurement file: "<run folder>/<file>" for a bench run's file (its
// folder holds run.json), "<campaign>/<run>/telemetry.csv" for a sim's (every run records the same
// file name), else the file's name.
std::string measurement_label(const std::filesystem::path& file);
// A name for what is made of the file (an output folder): the bench run's folder name,
// "<campaign>_<run>" for a sim's telemetry, else the file's stem. Only letters, digits and "._-+"
// (others become '_').
std::string measurement_name(const std::filesystem::path& file);

// File line of the header row (after "# key: value" metadata and blank lines).
std::size_t header_line(const std::filesystem::path& file);

// The error text for a file that is too short: "file:line:1: only N data rows; ... needs at least M".
[[noreturn]] void fail_too_short(const std::filesystem::path& file, std::size_t line, std::size_t rows);

}  // namespace hil::analysis
