#include "hil/csv_reader.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "hil/text_file.hpp"

namespace hil {
namespace {

constexpr std::size_t kReadBytes = 1 << 20, kMinReadBytes = 1 << 12;
// No measurement row comes near this; a file without line ends (a binary, /dev/zero) stops here
// instead of growing one line until memory runs out.
constexpr std::size_t kMaxLineBytes = std::size_t{16} << 20;

// Text from the file as an error quotes it (hil::printable), at most 60 bytes.
std::string printable(std::string_view text) { return hil::printable(text, 60); }

std::string trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return std::string(s);
}

// Splits on commas (no quoting: measurement files carry numbers and plain names).
void split(std::string_view line, std::vector<std::string_view>& fields) {
  fields.clear();
  std::size_t start = 0;
  for (std::size_t i = 0; i <= line.size(); ++i) {
    if (i == line.size() || line[i] == ',') {
      fields.push_back(line.substr(start, i - start));
      start = i + 1;
    }
  }
}

}  // namespace

CsvReader::CsvReader(const std::filesystem::path& file, CsvRequest request) : path_(file), request_(std::move(request)) {
  header_.file = file;
  std::error_code ec;
  if (std::filesystem::is_directory(file, ec)) throw CsvError(file.string() + ": is a folder, not a CSV file");
  file_ = std::fopen(file.c_str(), "rb");
  if (file_ == nullptr) throw CsvError(file.string() + ": cannot open the file: " + std::strerror(errno));
  // A constructor that throws runs no destructor: close the file on every error below, or each
  // refused file would keep its descriptor open (a long fuzz run ran out of them).
  struct CloseOnError {
    std::FILE*& file;
    bool armed = true;
    ~CloseOnError() {
      if (armed && file != nullptr) {
        std::fclose(file);
        file = nullptr;
      }
    }
  } close_on_error{file_};
  const std::uintmax_t size = std::filesystem::file_size(file, ec);
  file_bytes_ = ec ? 0 : size;  // 0: not known (a pipe, say)
  std::string line;
  for (;;) {
    if (!read_line(line)) {
      throw CsvError(file.string() + ":" + std::to_string(line_no_ + 1) + ":1: no header row (the file is empty)");
    }
    if (line_no_ == 1 && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);  // a UTF-8 byte order mark
    const std::string t = trim(line);
    if (const auto cr = t.find('\r'); cr != std::string::npos) {
      fail(
          line_no_, cr + 1,
          "a carriage return inside a line: the file's lines end in CR alone (old Mac style); save it with LF or CRLF line ends");
    }
    if (t.empty()) continue;
    if (t[0] == '#') {
      const auto colon = t.find(':');
      if (colon != std::string::npos) header_.metadata.emplace_back(trim(t.substr(1, colon - 1)), trim(t.substr(colon + 1)));
      continue;
    }
    break;
  }
  std::vector<std::string_view> fields;
  split(line, fields);
  for (auto f : fields) header_.names.push_back(trim(f));
  for (std::size_t i = 0; i < header_.names.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j) {
      if (header_.names[i] == header_.names[j] && !header_.names[i].empty()) {
        fail(line_no_, i + 1, "column '" + printable(header_.names[i]) + "' appears twice");
      }
    }
  }
  auto find = [&](const std::string& name) {
    const auto it = std::find(header_.names.begin(), header_.names.end(), name);
    return it == header_.names.end() ? -1 : static_cast<int>(it - header_.names.begin());
  };
  for (const auto& name : request_.required) {
    const int idx = find(name);
    if (idx < 0) {
      std::string have;
      for (const auto& n : header_.names) have += (have.empty() ? "" : ", ") + printable(n);
      fail(line_no_, 1, "missing required column '" + name + "' (the header has: " + have + ")");
    }
    field_of_.push_back(idx);
    header_.present.push_back(true);
  }
  for (const auto& name : request_.optional) {
    field_of_.push_back(find(name));
    header_.present.push_back(field_of_.back() >= 0);
  }
  close_on_error.armed = false;
}

CsvReader::~CsvReader() {
  if (file_ != nullptr) std::fclose(file_);
}

void CsvReader::fail(std::size_t line, std::size_t column, const std::string& what) const {
  throw CsvError(path_.string() + ":" + std::to_string(line) + ":" + std::to_string(column) + ": " + what);
}

bool CsvReader::read_line(std::string& line) {
  line.clear();
  for (;;) {
    const std::size_t nl = buffer_.find('\n', buffer_pos_);
    if (nl != std::string::npos) {
      line.append(buffer_, buffer_pos_, nl - buffer_pos_);
      consumed_ += nl - buffer_pos_ + 1;
      buffer_pos_ = nl + 1;
      ++line_no_;
      return true;
    }
    line.append(buffer_, buffer_pos_, std::string::npos);
    consumed_ += buffer_.size() - buffer_pos_;
    if (line.size() > kMaxLineBytes) {
      fail(line_no_ + 1, 1, "a line longer than " + std::to_string(kMaxLineBytes >> 20) + " MiB: not a measurement CSV");
    }
    buffer_.clear();
    buffer_pos_ = 0;
    if (eof_) {
      if (line.empty()) return false;
      ++line_no_;
      return true;  // last line without a newline
    }
    // A small file is read in one piece of its own size (+1 to see the end at once): a 1 MiB
    // buffer, zeroed, for a 2 KiB file was most of the time a small file took (the measurement
    // fuzz target ran about 50 x faster without it). Of unknown size (a pipe, or empty when opened
    // and being written): 1 MiB pieces.
    const std::size_t want =
        file_bytes_ == 0 ? kReadBytes
                         : static_cast<std::size_t>(std::clamp<std::uint64_t>(file_bytes_ + 1, kMinReadBytes, kReadBytes));
    buffer_.resize(want);
    const std::size_t n = std::fread(buffer_.data(), 1, want, file_);
    buffer_.resize(n);
    if (n < want) eof_ = true;
  }
}

bool CsvReader::next(CsvChunk& chunk, std::size_t max_rows) {
  chunk.values.assign(field_of_.size(), {});
  chunk.first_line = 0;
  chunk.lines.clear();
  std::string line;
  std::vector<std::string_view> fields;
  const int inc_index = [&] {
    if (request_.increasing.empty()) return -1;
    for (std::size_t c = 0; c < request_.required.size(); ++c)
      if (request_.required[c] == request_.increasing) return static_cast<int>(c);
    return -1;
  }();
  std::size_t rows = 0;
  while (rows < max_rows && read_line(line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    split(line, fields);
    if (fields.size() != header_.names.size()) {
      fail(line_no_, std::min(fields.size(), header_.names.size()) + 1,
           "expected " + std::to_string(header_.names.size()) + " fields as in the header, found " +
               std::to_string(fields.size()));
    }
    if (rows == 0) chunk.first_line = line_no_;
    chunk.lines.push_back(line_no_);
    for (std::size_t c = 0; c < field_of_.size(); ++c) {
      if (field_of_[c] < 0) continue;
      std::string_view cell = fields[static_cast<std::size_t>(field_of_[c])];
      while (!cell.empty() && cell.front() == ' ') cell.remove_prefix(1);
      while (!cell.empty() && cell.back() == ' ') cell.remove_suffix(1);
      double v = 0;
      const char* first = cell.data();
      if (!cell.empty() && cell.front() == '+') ++first;
      const auto [ptr, ec] = std::from_chars(first, cell.data() + cell.size(), v);
      const std::string& name =
          c < request_.required.size() ? request_.required[c] : request_.optional[c - request_.required.size()];
      if (cell.empty() || ec != std::errc() || ptr != cell.data() + cell.size() || !std::isfinite(v)) {
        fail(line_no_, static_cast<std::size_t>(field_of_[c]) + 1,
             "column '" + name + "': not a number: '" + printable(cell) + "'");
      }
      if (static_cast<int>(c) == inc_index) {
        if (have_last_ && !(v > last_increasing_)) {
          char msg[160];
          std::snprintf(msg, sizeof msg, "column '%s': %s goes backwards or repeats (%.9g after %.9g)", name.c_str(),
                        name.c_str(), v, last_increasing_);
          fail(line_no_, static_cast<std::size_t>(field_of_[c]) + 1, msg);
        }
        last_increasing_ = v;
        have_last_ = true;
      }
      chunk.values[c].push_back(v);
    }
    ++rows;
  }
  return rows > 0;
}

CsvChunk read_csv(const std::filesystem::path& file, const CsvRequest& request, CsvHeader* header) {
  CsvReader reader(file, request);
  CsvChunk all, part;
  all.values.assign(request.required.size() + request.optional.size(), {});
  bool first = true;
  while (reader.next(part)) {
    if (first) all.first_line = part.first_line, first = false;
    for (std::size_t c = 0; c < part.values.size(); ++c)
      all.values[c].insert(all.values[c].end(), part.values[c].begin(), part.values[c].end());
    all.lines.insert(all.lines.end(), part.lines.begin(), part.lines.end());
  }
  if (header) *header = reader.header();
  return all;
}

}  // namespace hil
