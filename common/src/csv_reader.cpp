#include "hil/csv_reader.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "hil/text_file.hpp"
#include "hil/unit_table.hpp"

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

// Splits on the separator (no quoting: measurement files carry numbers and plain names).
void split(std::string_view line, std::vector<std::string_view>& fields, char sep) {
  fields.clear();
  std::size_t start = 0;
  for (std::size_t i = 0; i <= line.size(); ++i) {
    if (i == line.size() || line[i] == sep) {
      fields.push_back(line.substr(start, i - start));
      start = i + 1;
    }
  }
}

std::string separator_name(char c) { return c == '\t' ? "tab" : std::string("'") + c + "'"; }

// A column name as quantity and unit: "t_ms" -> {t, ms}, "p [kPa]" / "p (kPa)" -> {p, kPa}; a
// name without a unit of hil::units::kUnits is all quantity ({"motion_intention", ""}).
struct NamedUnit {
  std::string quantity, unit;
};
NamedUnit parse_name(std::string_view name) {
  const std::string n = trim(name);
  if (!n.empty() && (n.back() == ']' || n.back() == ')')) {
    const auto at = n.rfind(n.back() == ']' ? '[' : '(');
    if (at != std::string::npos) {
      const std::string unit = trim(std::string_view(n).substr(at + 1, n.size() - at - 2));
      std::string q = trim(std::string_view(n).substr(0, at));
      while (!q.empty() && q.back() == '_') q.pop_back();
      if (units::find_unit(unit) && !q.empty()) return {q, unit};
    }
    return {n, ""};
  }
  const auto us = n.rfind('_');
  if (us != std::string::npos && us > 0 && units::find_unit(std::string_view(n).substr(us + 1)))
    return {n.substr(0, us), n.substr(us + 1)};
  return {n, ""};
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
  // The separator: the one asked for, else the one of ',' ';' tab that splits the header.
  char sep = request_.dialect.separator;
  std::vector<std::string_view> fields;
  if (sep == 0) {
    std::vector<char> splitting;
    for (const char c : {',', ';', '\t'}) {
      split(line, fields, c);
      if (fields.size() > 1) splitting.push_back(c);
    }
    if (splitting.size() > 1) {
      fail(line_no_, 1,
           "the header splits on both " + separator_name(splitting[0]) + " and " + separator_name(splitting[1]) +
               ": name the separator (--separator ';', ',' or tab)");
    }
    sep = splitting.empty() ? ',' : splitting.front();
  }
  header_.separator = sep;
  header_.decimal = request_.dialect.decimal != 0 ? request_.dialect.decimal : '.';
  decimal_known_ = request_.dialect.decimal != 0 || sep == ',';
  if (header_.decimal == sep)
    fail(line_no_, 1, "the decimal mark and the separator are both " + separator_name(sep) + ": name them apart");
  split(line, fields, sep);
  for (auto f : fields) header_.names.push_back(trim(f));
  for (std::size_t i = 0; i < header_.names.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j) {
      if (header_.names[i] == header_.names[j] && !header_.names[i].empty()) {
        fail(line_no_, i + 1, "column '" + printable(header_.names[i]) + "' appears twice");
      }
    }
  }
  resolve_columns();
  close_on_error.armed = false;
}

// Each requested column's field and unit factor: a --columns mapping, else the name itself, else
// the one column of the same quantity in another unit.
void CsvReader::resolve_columns() {
  const auto& names = header_.names;
  std::string have;
  for (const auto& n : names) have += (have.empty() ? "" : ", ") + printable(n);
  std::vector<std::string> all = request_.required;
  all.insert(all.end(), request_.optional.begin(), request_.optional.end());
  for (const auto& [key, column] : request_.dialect.columns) {
    const std::string q = parse_name(key).quantity;
    if (std::none_of(all.begin(), all.end(), [&](const std::string& a) { return parse_name(a).quantity == q; })) {
      std::string known;
      for (const auto& a : all) known += (known.empty() ? "" : ", ") + a;
      throw CsvError("--columns " + printable(key) + "=" + printable(column) + ": '" + printable(key) +
                     "' is none of the columns read (" + known + ")");
    }
  }
  for (std::size_t c = 0; c < all.size(); ++c) {
    const NamedUnit want = parse_name(all[c]);
    int idx = -1;
    double scale = 1;
    const auto mapped = std::find_if(request_.dialect.columns.begin(), request_.dialect.columns.end(),
                                     [&](const auto& kv) { return parse_name(kv.first).quantity == want.quantity; });
    if (mapped != request_.dialect.columns.end()) {
      const auto it = std::find(names.begin(), names.end(), mapped->second);
      if (it == names.end())
        fail(line_no_, 1,
             "--columns " + printable(mapped->first) + "=" + printable(mapped->second) + ": the header has no column '" +
                 printable(mapped->second) + "' (it has: " + have + ")");
      idx = static_cast<int>(it - names.begin());
      const std::string given = parse_name(mapped->first).unit, named = parse_name(*it).unit;
      if (!given.empty() && !named.empty() && !units::same_letters(given, named))
        fail(line_no_, static_cast<std::size_t>(idx) + 1,
             "--columns " + printable(mapped->first) + "=" + printable(mapped->second) + ": the column says " + named +
                 ", the option " + given + ": give the unit once (--columns " + want.quantity + "=" + printable(*it) + ")");
      const std::string unit = given.empty() ? named : given;
      if (unit.empty())
        fail(line_no_, static_cast<std::size_t>(idx) + 1,
             "column '" + printable(*it) + "' for " + want.quantity + " names no unit: give it, e.g. --columns " + all[c] + "=" +
                 printable(*it));
      const auto f = units::conversion(unit, want.unit);
      if (!f)
        fail(line_no_, static_cast<std::size_t>(idx) + 1,
             "--columns " + printable(mapped->first) + ": '" + printable(unit) + "' is no unit of " + want.quantity + " (" +
                 all[c] + " is in " + want.unit + ")");
      scale = *f;
    } else if (const auto it = std::find(names.begin(), names.end(), all[c]); it != names.end()) {
      idx = static_cast<int>(it - names.begin());
    } else {
      for (std::size_t i = 0; i < names.size(); ++i) {
        const NamedUnit got = parse_name(names[i]);
        if (got.unit.empty() || !units::same_letters(got.quantity, want.quantity)) continue;
        const auto f = units::conversion(got.unit, want.unit);
        if (!f) continue;
        if (idx >= 0)
          fail(line_no_, i + 1,
               "columns '" + printable(names[static_cast<std::size_t>(idx)]) + "' and '" + printable(names[i]) +
                   "' both read as " + all[c] + ": name the one to use with --columns " + all[c] + "=NAME");
        idx = static_cast<int>(i), scale = *f;
      }
    }
    if (idx < 0 && c < request_.required.size())
      fail(line_no_, 1,
           "missing required column '" + all[c] + "' (the header has: " + have + "); a column of another name: --columns " +
               all[c] + "=NAME");
    field_of_.push_back(idx);
    scale_.push_back(scale);
    header_.present.push_back(idx >= 0);
  }
  header_.field = field_of_;
}

// One cell as a number, with the file's decimal mark (read off the first cell that shows one).
bool CsvReader::parse_cell(std::string_view cell, double& v) {
  const char* first = cell.data();
  const char* last = cell.data() + cell.size();
  if (!cell.empty() && cell.front() == '+') ++first;
  if (!decimal_known_) {
    const bool comma = cell.find(',') != std::string_view::npos, point = cell.find('.') != std::string_view::npos;
    if (comma != point) header_.decimal = comma ? ',' : '.', decimal_known_ = true, decimal_line_ = line_no_;
  }
  char buf[64] = {};
  if (header_.decimal == ',' && cell.size() < sizeof buf) {
    const std::size_t n = static_cast<std::size_t>(last - first);
    for (std::size_t i = 0; i < n; ++i) buf[i] = first[i] == ',' ? '.' : first[i] == '.' ? ',' : first[i];
    first = buf, last = buf + n;
  }
  const auto [ptr, ec] = std::from_chars(first, last, v);
  return !cell.empty() && ec == std::errc() && ptr == last && std::isfinite(v);
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
  chunk.restarts.clear();
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
    split(line, fields, header_.separator);
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
      const std::string& name =
          c < request_.required.size() ? request_.required[c] : request_.optional[c - request_.required.size()];
      if (!parse_cell(cell, v)) {
        const char other = header_.decimal == '.' ? ',' : '.';
        const std::string mark = cell.find(other) != std::string_view::npos && header_.separator != ','
                                     ? std::string("; the decimal mark is '") + header_.decimal + "'" +
                                           (decimal_line_ ? " as line " + std::to_string(decimal_line_) + " shows" : "") +
                                           " (name it: --decimal '" + other + "')"
                                     : "";
        fail(line_no_, static_cast<std::size_t>(field_of_[c]) + 1,
             "column '" + name + "': not a number: '" + printable(cell) + "'" + mark);
      }
      if (scale_[c] != 1) v *= scale_[c];
      if (static_cast<int>(c) == inc_index) {
        if (have_last_ && !(v > last_increasing_) && request_.restarts && v <= first_increasing_) {
          chunk.restarts.push_back(rows);  // a second acquisition, its clock restarted
          first_increasing_ = v;
        } else if (have_last_ && !(v > last_increasing_)) {
          char msg[300];
          std::snprintf(msg, sizeof msg, "column '%s': %s goes backwards or repeats (%.9g after %.9g)%s", name.c_str(),
                        name.c_str(), v, last_increasing_,
                        v <= first_increasing_ ? "; it restarts at or below the first row's, as a second acquisition "
                                                 "appended to the file would (diagnose reads each as a file of one rig)"
                                               : "");
          fail(line_no_, static_cast<std::size_t>(field_of_[c]) + 1, msg);
        }
        if (!have_last_) first_increasing_ = v;
        last_increasing_ = v;
        have_last_ = true;
      }
      chunk.values[c].push_back(v);
    }
    ++rows;
  }
  return rows > 0;
}

CsvDialect csv_dialect(const std::string& separator, const std::string& decimal, const std::string& columns) {
  CsvDialect d;
  if (separator == "tab" || separator == "\t") {
    d.separator = '\t';
  } else if (separator == "," || separator == ";") {
    d.separator = separator[0];
  } else if (!separator.empty()) {
    throw CsvError("--separator '" + printable(separator) + "': give ',', ';' or tab");
  }
  if (decimal == "." || decimal == ",") {
    d.decimal = decimal[0];
  } else if (!decimal.empty()) {
    throw CsvError("--decimal '" + printable(decimal) + "': give '.' or ','");
  }
  if (d.separator != 0 && d.separator == d.decimal) throw CsvError("--separator and --decimal are both '" + decimal + "'");
  std::size_t start = 0;
  while (start < columns.size()) {
    const std::size_t end = std::min(columns.find(',', start), columns.size());
    const std::string item = trim(std::string_view(columns).substr(start, end - start));
    const auto eq = item.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == item.size())
      throw CsvError("--columns '" + printable(item) + "': give COLUMN=NAME, e.g. t_s=time,p_meas_bar=P1");
    const std::string key = trim(std::string_view(item).substr(0, eq)), name = trim(std::string_view(item).substr(eq + 1));
    for (const auto& [k, v] : d.columns)
      if (parse_name(k).quantity == parse_name(key).quantity)
        throw CsvError("--columns names " + parse_name(key).quantity + " twice ('" + printable(k) + "' and '" + printable(key) +
                       "')");
    d.columns.emplace_back(key, name);
    start = end + 1;
  }
  return d;
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
