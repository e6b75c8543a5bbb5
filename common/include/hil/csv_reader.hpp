// A strict, streaming CSV reader for measurement files (physics.md section 4): a header row,
// optionally preceded by "# key: value" metadata lines. Only the requested columns are parsed;
// any other column is ignored, not rejected. Every error names file, line and column:
//   "run.csv:1204:3: column 'p_meas_mpa': not a number: 'abc'".
// Setup/offline code: allocates and throws.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace hil {

class CsvError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// How a lab's logger writes its CSV. Unset fields are read off the file: the separator from the
// header (the one of ',' ';' tab that splits it; two that both do are refused, naming the option),
// the decimal mark from the first cell holding '.' or ',' (',' only beside another separator).
struct CsvDialect {
  char separator = 0;  // 0: detected
  char decimal = 0;    // 0: detected
  // A requested column read from the file's column of another name: {"t_s", "time"}; the
  // request's unit may be named anew ({"p_meas_bar", "P1"}: P1 holds the pressure in bar).
  std::vector<std::pair<std::string, std::string>> columns;
};

// The requested names carry their units ("t_s", "p_meas_mpa": quantity, '_', unit of
// hil::units::kUnits). A column of the file matches one of them by its name, else by the same
// quantity in another unit ("t_ms", "t [ms]", "p_meas (bar)") whose values are converted on reading.
struct CsvRequest {
  std::vector<std::string> required;  // must be present
  std::vector<std::string> optional;  // parsed when present
  std::string increasing;             // a column that must strictly increase (time); may be empty
  CsvDialect dialect{};
  // The increasing column may restart at or below the first value of its run: a second
  // acquisition appended to the file (CsvChunk::restarts). Otherwise that is an error.
  bool restarts = false;
};

struct CsvHeader {
  std::filesystem::path file;
  std::vector<std::pair<std::string, std::string>> metadata;
  std::vector<std::string> names;  // every column in the file
  std::vector<bool> present;       // per requested column (required then optional)
  std::vector<int> field;          // per requested column: its index in `names` (-1: absent)
  char separator = ',', decimal = '.';
};

// A block of consecutive rows: values[c][r] for requested column c (required then optional; a
// missing optional column has an empty vector), first_line = file line of row 0, lines[r] = file
// line of row r (blank and comment lines may sit between rows), for callers' own error messages.
struct CsvChunk {
  std::vector<std::vector<double>> values;
  std::size_t first_line = 0;
  std::vector<std::size_t> lines;
  std::vector<std::size_t> restarts;  // rows where the increasing column restarted (CsvRequest::restarts)
  std::size_t rows() const { return values.empty() ? 0 : values.front().size(); }
};

class CsvReader {
 public:
  CsvReader(const std::filesystem::path& file, CsvRequest request);
  ~CsvReader();
  CsvReader(const CsvReader&) = delete;
  CsvReader& operator=(const CsvReader&) = delete;

  const CsvHeader& header() const { return header_; }
  // Reads up to max_rows rows into `chunk`; returns false at the end of the file.
  bool next(CsvChunk& chunk, std::size_t max_rows = 65536);
  std::uint64_t bytes_read() const { return consumed_; }
  std::uint64_t file_bytes() const { return file_bytes_; }

 private:
  bool read_line(std::string& line);
  [[noreturn]] void fail(std::size_t line, std::size_t column, const std::string& what) const;

  std::filesystem::path path_;
  CsvRequest request_;
  CsvHeader header_;
  std::FILE* file_ = nullptr;
  std::vector<int> field_of_;  // requested column -> field index in the file, -1 = absent
  std::size_t line_no_ = 0;
  std::uint64_t consumed_ = 0, file_bytes_ = 0;
  std::vector<double> scale_;  // requested column -> factor from the file's unit to the request's
  double last_increasing_ = 0, first_increasing_ = 0;
  bool have_last_ = false;
  bool decimal_known_ = false;
  std::size_t decimal_line_ = 0;  // the line the decimal mark was read off
  void resolve_columns();
  bool parse_cell(std::string_view cell, double& v);
  std::string buffer_;
  std::size_t buffer_pos_ = 0;
  bool eof_ = false;
};

// A dialect from the command line's words: separator "," ";" "tab" (or a tab), decimal "." ",",
// columns "t_s=time,p_meas_bar=P1" (empty: detected / none). Throws CsvError naming the option.
CsvDialect csv_dialect(const std::string& separator, const std::string& decimal, const std::string& columns);

// Reads the whole file (convenience for small files and tests).
CsvChunk read_csv(const std::filesystem::path& file, const CsvRequest& request, CsvHeader* header = nullptr);

}  // namespace hil
