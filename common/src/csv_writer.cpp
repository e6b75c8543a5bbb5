#include "hil/csv_writer.hpp"

#include <charconv>
#include <cmath>
#include <stdexcept>
#include <system_error>

namespace hil {
namespace {
constexpr std::size_t kFlushBytes = 1 << 16;
}

CsvWriter::CsvWriter(const std::filesystem::path& file, std::vector<CsvColumn> columns,
                     const std::vector<std::pair<std::string, std::string>>& metadata)
    : path_(file), columns_(std::move(columns)) {
  file_ = std::fopen(file.c_str(), "wb");
  if (file_ == nullptr) {
    throw std::system_error(errno, std::generic_category(), "cannot write " + file.string());
  }
  buffer_.reserve(2 * kFlushBytes);
  for (const auto& [key, value] : metadata) put("# " + key + ": " + value + "\n");
  for (std::size_t i = 0; i < columns_.size(); ++i) {
    put(columns_[i].name);
    put(i + 1 < columns_.size() ? "," : "\n");
  }
}

CsvWriter::~CsvWriter() {
  if (file_ == nullptr) return;
  std::fwrite(buffer_.data(), 1, buffer_.size(), file_);
  std::fclose(file_);
}

void CsvWriter::put(std::string_view text) { buffer_.append(text); }

void CsvWriter::row(std::span<const double> values) {
  char cell[64];
  for (std::size_t i = 0; i < columns_.size(); ++i) {
    const double v = i < values.size() ? values[i] : NAN;
    if (std::isfinite(v)) {
      const auto res = std::to_chars(cell, cell + sizeof cell, v, std::chars_format::fixed,
                                     columns_[i].decimals);
      buffer_.append(cell, res.ptr);
    } else {
      buffer_.append("nan");
    }
    buffer_.push_back(i + 1 < columns_.size() ? ',' : '\n');
  }
  ++rows_;
  if (buffer_.size() >= kFlushBytes) flush();
}

void CsvWriter::flush() {
  if (file_ == nullptr || buffer_.empty()) return;
  const std::size_t n = std::fwrite(buffer_.data(), 1, buffer_.size(), file_);
  const bool ok = n == buffer_.size() && std::fflush(file_) == 0;
  buffer_.clear();
  if (!ok) throw std::system_error(errno, std::generic_category(), "writing " + path_.string());
}

void CsvWriter::close() {
  if (file_ == nullptr) return;
  flush();
  const int rc = std::fclose(file_);
  file_ = nullptr;
  if (rc != 0) throw std::system_error(errno, std::generic_category(), "closing " + path_.string());
}

}  // namespace hil
