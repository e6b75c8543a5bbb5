// Measurement files (physics.md section 4): t_s, theta_cmd_deg, p_meas_mpa required; the motor
// encoder theta_motor_deg and the reference p_ref_mpa optional; any other column is ignored.
// Read through hil::CsvReader, so a missing column, a non-numeric cell or time going backwards
// is a CsvError naming file:line:column. Values are converted to SI here, once.
// Setup/offline code: allocates and throws.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "hil/csv_reader.hpp"

namespace hil::analysis {

// Rows of a measurement in SI. theta_motor_rad / p_ref_pa are empty when the file lacks them.
struct MeasurementRows {
  std::vector<double> t_s, theta_cmd_rad, p_meas_pa, theta_motor_rad, p_ref_pa;
  std::size_t size() const { return t_s.size(); }
  void clear();
  void append(const MeasurementRows& other);
};

// Streams a measurement file in chunks (bounded memory for hour-long files).
class MeasurementReader {
 public:
  explicit MeasurementReader(const std::filesystem::path& file);
  bool has_encoder() const { return has_encoder_; }
  bool has_reference() const { return has_reference_; }
  const CsvHeader& header() const { return reader_.header(); }
  const std::filesystem::path& file() const { return file_; }
  // Next chunk of up to max_rows rows; false at the end. first_line: file line of the chunk's row 0.
  bool next(MeasurementRows& rows, std::size_t max_rows = 65536);
  std::size_t first_line() const { return first_line_; }  // of the last chunk
  std::size_t rows_read() const { return rows_read_; }
  std::size_t first_data_line() const { return first_data_line_; }  // file line of row 0
  double progress() const;  // fraction of the file's bytes consumed

 private:
  std::filesystem::path file_;
  CsvReader reader_;
  CsvChunk chunk_;
  bool has_encoder_ = false, has_reference_ = false;
  std::size_t first_line_ = 0, rows_read_ = 0, first_data_line_ = 0;
};

// A whole measurement in memory (diagnose, tests).
struct Measurement {
  std::filesystem::path file;
  MeasurementRows rows;
  bool has_encoder = false, has_reference = false;
  std::size_t first_data_line = 0;  // file line of row 0, for messages
  std::vector<std::pair<std::string, std::string>> metadata;
};

// Minimum rows for compare and diagnose (a fit needs a settle window and some dynamics).
inline constexpr std::size_t kMinRows = 50;

// Loads the whole file; throws CsvError (file:line:column) for bad content and for a file with
// fewer than kMinRows data rows ("too short to fit").
Measurement load_measurement(const std::filesystem::path& file);

// File line of the header row (after "# key: value" metadata and blank lines).
std::size_t header_line(const std::filesystem::path& file);

// The error text for a file that is too short: "file:line:1: only N data rows; ... needs at least M".
[[noreturn]] void fail_too_short(const std::filesystem::path& file, std::size_t line, std::size_t rows);

}  // namespace hil::analysis
