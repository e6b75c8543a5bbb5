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

struct CsvRequest {
  std::vector<std::string> required;  // must be present
  std::vector<std::string> optional;  // parsed when present
  std::string increasing;             // a column that must strictly increase (time); may be empty
};

struct CsvHeader {
  std::filesystem::path file;
  std::vector<std::pair<std::string, std::string>> metadata;
  std::vector<std::string> names;  // every column in the file
  std::vector<bool> present;       // per requested column (required then optional)
};

// A block of consecutive rows: values[c][r] for requested column c (required then optional; a
// missing optional column has an empty vector), first_line = file line of row 0, lines[r] = file
// line of row r (blank and comment lines may sit between rows), for callers' own error messages.
struct CsvChunk {
  std::vector<std::vector<double>> values;
  std::size_t first_line = 0;
  std::vector<std::size_t> lines;
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
  double last_increasing_ = 0;
  bool have_last_ = false;
  std::string buffer_;
  std::size_t buffer_pos_ = 0;
  bool eof_ = false;
};

// Reads the whole file (convenience for small files and tests).
CsvChunk read_csv(const std::filesystem::path& file, const CsvRequest& request, CsvHeader* header = nullptr);

}  // namespace hil
