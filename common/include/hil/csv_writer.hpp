// A buffered CSV writer for telemetry and measurement files (physics.md section 4 schema).
// Numbers are formatted with std::to_chars at a fixed number of decimals per column, which keeps
// writing an hour at 1 kHz to a few seconds. Not real-time safe: it does file I/O.
#pragma once

#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "hil/line_file.hpp"

namespace hil {

struct CsvColumn {
  std::string name;  // carries its unit, e.g. "p_meas_mpa"
  int decimals;      // fixed-point digits after the decimal point
};

// Fixed-point text of a finite v with `decimals` digits into [out, end) (room for 32 characters),
// as telemetry.csv writes it (and telemetry.mcap, so both carry the same numbers); returns the end.
char* format_fixed(char* out, char* end, double v, int decimals);

class CsvWriter {
 public:
  // Opens `file` for writing (truncating), writes the "# key: value" metadata lines, then the header.
  CsvWriter(const std::filesystem::path& file, std::vector<CsvColumn> columns,
            const std::vector<std::pair<std::string, std::string>>& metadata = {});
  ~CsvWriter();
  CsvWriter(const CsvWriter&) = delete;
  CsvWriter& operator=(const CsvWriter&) = delete;

  // One value per column, in column order. A non-finite value is written as "nan" so that a
  // reader rejects it loudly instead of the writer hiding it. May flush (and so throw, see flush).
  void row(std::span<const double> values);
  // Pushes buffered rows to the OS (so a crash of this process after it loses nothing). When the
  // disk refuses them, the file keeps only whole rows, the buffered rows are dropped (counted in
  // rows_dropped) and this throws std::system_error naming the file.
  void flush();
  void close();                                       // flushes and closes; throws as flush does
  std::size_t rows_written() const { return rows_; }  // handed in by row()
  std::size_t rows_on_disk() const { return rows_ - rows_buffered_ - rows_dropped_; }
  std::size_t rows_dropped() const { return rows_dropped_; }  // handed in, refused by the disk
  const std::vector<CsvColumn>& columns() const { return columns_; }

 private:
  void put(std::string_view text);

  std::unique_ptr<LineFile> file_;
  std::vector<CsvColumn> columns_;
  std::string buffer_;
  std::size_t rows_ = 0, rows_buffered_ = 0, rows_dropped_ = 0;
};

}  // namespace hil
