#include "telemetry_range.hpp"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string_view>

#include "hil/bench/server/runner.hpp"
#include "hil/config.hpp"
#include "hil/telemetry_schema.hpp"

namespace hil::bench {
namespace {

// The recorder's lines are ~150 bytes; a longer one than this is no telemetry.csv of ours.
constexpr std::size_t kMaxLineBytes = 64 * 1024;
// Below this many bytes between the bisection's bounds, reading on is cheaper than probing.
constexpr std::uint64_t kScanBytes = 8 * 1024;

// Whole lines of the file from a byte on, read with pread in chunks of `chunk` bytes.
class LineReader {
 public:
  LineReader(int fd, std::uint64_t size, const std::string& name, std::uint64_t from, std::size_t chunk)
      : fd_(fd), size_(size), name_(name), base_(from), chunk_(chunk) {}

  // The next line without its '\n' and the byte it starts at; false at the end (a last line
  // without '\n' is one being written: not yet a row).
  bool next(std::string_view& line, std::uint64_t& at) {
    for (;;) {
      const auto nl = buf_.find('\n', pos_);
      if ((nl == std::string::npos ? buf_.size() : nl) - pos_ > kMaxLineBytes)
        throw std::runtime_error(name_ + ": byte " + std::to_string(base_ + pos_) +
                                 ": a line longer than 64 KiB (no telemetry.csv)");
      if (nl != std::string::npos) {
        line = std::string_view(buf_).substr(pos_, nl - pos_);
        at = base_ + pos_;
        pos_ = nl + 1;
        return true;
      }
      base_ += pos_;
      buf_.erase(0, pos_);
      pos_ = 0;
      const std::uint64_t at_end = base_ + buf_.size();
      if (at_end >= size_) return false;
      const std::size_t want = static_cast<std::size_t>(std::min<std::uint64_t>(chunk_, size_ - at_end));
      const std::size_t had = buf_.size();
      buf_.resize(had + want);
      ssize_t got = 0;
      do got = ::pread(fd_, buf_.data() + had, want, static_cast<off_t>(at_end));
      while (got < 0 && errno == EINTR);
      if (got < 0) throw std::runtime_error(name_ + ": cannot read (" + std::strerror(errno) + ")");
      buf_.resize(had + static_cast<std::size_t>(got));
      if (got == 0) return false;  // shorter than it was: nothing more to read
    }
  }

 private:
  int fd_;
  std::uint64_t size_;
  const std::string& name_;
  std::uint64_t base_;  // the file's byte at buf_[0]
  std::size_t chunk_;
  std::string buf_;
  std::size_t pos_ = 0;
};

// A number at the start of `text` up to the next ',' (the cell), or NaN.
double cell_value(std::string_view cell) {
  double v = std::nan("");
  const auto r = std::from_chars(cell.data(), cell.data() + cell.size(), v);
  return r.ec == std::errc() && r.ptr == cell.data() + cell.size() ? v : std::nan("");
}

std::string_view first_cell(std::string_view line) { return line.substr(0, line.find(',')); }

void append_json_number(std::string& out, double v) {
  if (!std::isfinite(v)) {
    out += "null";
    return;
  }
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);  // shortest text that reads back as v
  out.append(buf, r.ptr);
}

}  // namespace

std::string telemetry_range_json(int fd, std::uint64_t size, const std::string& name, const TelemetryRange& q) {
  // The header: the first line that is not a "# key: value" comment.
  LineReader head(fd, size, name, 0, 4096);
  std::string_view line;
  std::uint64_t at = 0;
  std::vector<std::string> header;
  while (head.next(line, at)) {
    if (!line.empty() && line[0] == '#') continue;
    for (std::size_t b = 0; b <= line.size();) {
      const auto e = std::min(line.find(',', b), line.size());
      header.emplace_back(line.substr(b, e - b));
      b = e + 1;
    }
    break;
  }
  if (header.empty() || header[0] != telemetry::name(telemetry::Col::t_s))
    throw std::runtime_error(name + ": no telemetry header (a line whose first column is t_s)");
  const std::uint64_t data_start = at + line.size() + 1;

  // The requested columns: schema names, in the request's order, each once; their cell in a row.
  std::vector<std::string> names;
  for (const auto& c : telemetry::kColumns) names.emplace_back(c.name);
  std::vector<std::string> given, absent;
  std::vector<std::size_t> cell;
  for (const auto& c : q.columns) {
    if (std::find(names.begin(), names.end(), c) == names.end()) {
      const std::string hint = cfg::closest(c, names);
      throw BadField("columns", "'columns': '" + c.substr(0, 40) + "' is no telemetry column" +
                                    (hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
    }
    if (c == names[0] || std::find(given.begin(), given.end(), c) != given.end() ||
        std::find(absent.begin(), absent.end(), c) != absent.end())
      continue;
    const auto k = std::find(header.begin(), header.end(), c);
    if (k == header.end()) {
      absent.push_back(c);
    } else {
      given.push_back(c);
      cell.push_back(static_cast<std::size_t>(k - header.begin()));
    }
  }

  // Bisection on byte offsets: `lo` stays the start of a row before from_s (or the first row).
  const auto row_time_after = [&](std::uint64_t byte, std::uint64_t& start) {
    LineReader r(fd, size, name, byte - 1, 512);
    std::string_view l;
    if (!r.next(l, start) || !r.next(l, start)) return std::nan("");  // through the line holding byte-1; then the row
    return cell_value(first_cell(l));
  };
  std::uint64_t lo = data_start, hi = size;
  while (hi > lo && hi - lo > kScanBytes) {
    const std::uint64_t mid = lo + (hi - lo) / 2;
    std::uint64_t start = 0;
    const double t = row_time_after(mid, start);
    if (std::isfinite(t) && t < q.from_s && start < hi)
      lo = start;
    else
      hi = mid;
  }

  std::string t_out = "[";
  std::vector<std::string> out(given.size(), "[");
  std::uint64_t rows = 0;
  LineReader scan(fd, size, name, lo, 64 * 1024);
  std::vector<std::string_view> cells;
  while (scan.next(line, at)) {
    if (line.empty() || line[0] == '#') continue;
    const double t = cell_value(first_cell(line));
    if (!std::isfinite(t)) throw std::runtime_error(name + ": byte " + std::to_string(at) + ": t_s is no number");
    if (t < q.from_s) continue;
    if (t > q.to_s) break;
    if (rows == q.max_rows) {
      char msg[200];
      std::snprintf(msg, sizeof msg, "'to_s': %.6g to %.6g s holds more than %llu rows (max_rows): ask a shorter range", q.from_s,
                    q.to_s, static_cast<unsigned long long>(q.max_rows));
      throw BadField("to_s", msg);
    }
    cells.clear();
    for (std::size_t b = 0; b <= line.size();) {
      const auto e = std::min(line.find(',', b), line.size());
      cells.push_back(line.substr(b, e - b));
      b = e + 1;
    }
    const char* sep = rows == 0 ? "" : ",";
    t_out += sep;
    append_json_number(t_out, t);
    for (std::size_t i = 0; i < given.size(); ++i) {
      out[i] += sep;
      append_json_number(out[i], cell[i] < cells.size() ? cell_value(cells[cell[i]]) : std::nan(""));
    }
    ++rows;
  }

  std::string json = "{\"from_s\":";
  append_json_number(json, q.from_s);
  json += ",\"to_s\":";
  append_json_number(json, q.to_s);
  json += ",\"rows\":" + std::to_string(rows) + ",\"t_s\":" + t_out + "],\"columns\":{";
  for (std::size_t i = 0; i < given.size(); ++i) json += (i ? ",\"" : "\"") + given[i] + "\":" + out[i] + "]";
  json += "},\"absent\":[";
  for (std::size_t i = 0; i < absent.size(); ++i) json += (i ? ",\"" : "\"") + absent[i] + "\"";
  json += "]}";
  return json;
}

}  // namespace hil::bench
