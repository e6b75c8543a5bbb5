// A table of telemetry read from either file a run records: telemetry.csv (through CsvReader) or
// telemetry.mcap (the messages of its telemetry topic, one row each, through mcap::Reader). The
// kind is told by the file's first bytes, not its name. Both give the same CsvHeader and
// CsvChunk, so the measurement reader and the run report read either the same way; in an MCAP
// table CsvChunk::lines holds each row's record offset in the file, which where() words as such.
// Errors are CsvError (McapError is one), naming file and line:column or record offset.
// Setup/offline code: allocates and throws.
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <string_view>

#include "hil/csv_reader.hpp"
#include "hil/mcap.hpp"

namespace hil {

bool is_mcap_file(const std::filesystem::path& file);  // starts with the MCAP magic

class TableReader {
 public:
  // topic: the MCAP channel whose JSON messages are the rows (ignored for a CSV).
  TableReader(const std::filesystem::path& file, CsvRequest request, std::string_view topic);
  ~TableReader();
  TableReader(const TableReader&) = delete;
  TableReader& operator=(const TableReader&) = delete;

  const CsvHeader& header() const { return header_; }
  bool next(CsvChunk& chunk, std::size_t max_rows = 65536);
  std::uint64_t bytes_read() const;
  std::uint64_t file_bytes() const;
  bool is_mcap() const { return mcap_ != nullptr; }
  // Where row `line` (a CsvChunk::lines entry) sits, for a message about `column`:
  // "file:LINE:COL: column 'x'" for a CSV, "file: record at byte N (topic T): column 'x'" for an MCAP.
  std::string where(std::size_t line, std::string_view column) const;

 private:
  [[noreturn]] void fail(std::uint64_t offset, const std::string& what) const;
  std::unique_ptr<CsvReader> csv_;
  std::unique_ptr<mcap::Reader> mcap_;
  std::string topic_;
  CsvRequest request_;
  CsvHeader header_;
  std::uint16_t channel_ = 0;
  mcap::Message pending_;
  bool has_pending_ = false;
  std::vector<int> field_of_;  // requested column -> its index in header_.names, -1 = absent
  double last_increasing_ = 0;
  bool have_last_ = false;
};

}  // namespace hil
