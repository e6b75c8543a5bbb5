// A buffered CSV writer for telemetry and measurement files (physics.md section 4 schema).
// Numbers are formatted with std::to_chars at a fixed number of decimals per column, which keeps
// writing an hour at 1 kHz to a few seconds. Not real-time safe: it does file I/O.
#pragma once

#include <cstdio>
#include <filesystem>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace hil {

struct CsvColumn {
  std::string name;  // carries its unit, e.g. "p_meas_mpa"
  int decimals;      // fixed-point digits after the decimal point
};

class CsvWriter {
 public:
  // Opens `file` for writing (truncating), writes the "# key: value" metadata lines, then the header.
  CsvWriter(const std::filesystem::path& file, std::vector<CsvColumn> columns,
            const std::vector<std::pair<std::string, std::string>>& metadata = {});
  ~CsvWriter();
  CsvWriter(const CsvWriter&) = delete;
  CsvWriter& operator=(const CsvWriter&) = delete;

  // One value per column, in column order. A non-finite value is written as "nan" so that a
  // reader rejects it loudly instead of the writer hiding it.
  void row(std::span<const double> values);
  void flush();  // pushes buffered rows to the OS (so a crash after this loses nothing)
  void close();  // flushes and closes; throws if the disk refused anything
  std::size_t rows_written() const { return rows_; }
  const std::vector<CsvColumn>& columns() const { return columns_; }

 private:
  void put(std::string_view text);

  std::filesystem::path path_;
  std::FILE* file_ = nullptr;
  std::vector<CsvColumn> columns_;
  std::string buffer_;
  std::size_t rows_ = 0;
};

}  // namespace hil
