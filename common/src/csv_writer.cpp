#include "hil/csv_writer.hpp"

#include <charconv>
#include <cmath>
#include <stdexcept>

namespace hil {
namespace {
constexpr std::size_t kFlushBytes = 1 << 16;
constexpr double kPow10[] = {1, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9};
constexpr unsigned long long kPow10U[] = {1, 10, 100, 1000, 10000, 100000, 1000000, 10000000, 100000000, 1000000000};

}  // namespace

// As a scaled integer when it fits (about 4x faster than std::to_chars with a precision, which
// dominated writing telemetry); a value too large for that gets its shortest exact form instead
// (1e+300 in fixed notation is 300 digits).
char* format_fixed(char* out, char* end, double v, int decimals) {
  if (decimals >= 0 && decimals <= 9 && std::abs(v) * kPow10[decimals] < 9e15) {
    long long scaled = std::llround(v * kPow10[decimals]);
    if (scaled < 0) *out++ = '-', scaled = -scaled;
    const auto u = static_cast<unsigned long long>(scaled);
    out = std::to_chars(out, end, u / kPow10U[decimals]).ptr;
    if (decimals > 0) {
      *out++ = '.';
      unsigned long long frac = u % kPow10U[decimals];
      for (int i = decimals - 1; i >= 0; --i) out[i] = static_cast<char>('0' + frac % 10), frac /= 10;
      out += decimals;
    }
    return out;
  }
  return std::to_chars(out, end, v).ptr;
}

CsvWriter::CsvWriter(const std::filesystem::path& file, std::vector<CsvColumn> columns,
                     const std::vector<std::pair<std::string, std::string>>& metadata)
    : file_(std::make_unique<LineFile>(file)), columns_(std::move(columns)) {
  buffer_.reserve(2 * kFlushBytes);
  for (const auto& [key, value] : metadata) put("# " + key + ": " + value + "\n");
  for (std::size_t i = 0; i < columns_.size(); ++i) {
    put(columns_[i].name);
    put(i + 1 < columns_.size() ? "," : "\n");
  }
}

CsvWriter::~CsvWriter() {
  try {
    flush();
  } catch (const std::exception&) {  // a destructor cannot report it; close() does
  }
}

void CsvWriter::put(std::string_view text) { buffer_.append(text); }

void CsvWriter::row(std::span<const double> values) {
  char cell[64];
  for (std::size_t i = 0; i < columns_.size(); ++i) {
    const double v = i < values.size() ? values[i] : NAN;
    if (std::isfinite(v)) {
      buffer_.append(cell, format_fixed(cell, cell + sizeof cell, v, columns_[i].decimals));
    } else {
      buffer_.append("nan");
    }
    buffer_.push_back(i + 1 < columns_.size() ? ',' : '\n');
  }
  ++rows_;
  ++rows_buffered_;
  if (buffer_.size() >= kFlushBytes) flush();
}

void CsvWriter::flush() {
  if (!file_ || buffer_.empty()) return;
  const std::size_t rows = rows_buffered_;
  rows_buffered_ = 0;
  try {
    file_->append(buffer_);
  } catch (...) {
    rows_dropped_ += rows;
    buffer_.clear();
    throw;
  }
  buffer_.clear();
}

void CsvWriter::close() {
  if (!file_) return;
  flush();
  file_.reset();
}

}  // namespace hil
