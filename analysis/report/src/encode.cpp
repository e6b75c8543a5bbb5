#include "encode.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#include <nlohmann/json.hpp>

#include "hil/minmax_decimator.hpp"

namespace hil::report::detail {
namespace {

constexpr double kPow10[] = {1e-4, 1e-3, 1e-2, 1e-1, 1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10};
double pow10(int e) { return kPow10[e + 4]; }  // e in [-4, 10]

constexpr auto kDigitPairsTable = [] {
  std::array<char, 200> t{};
  for (int i = 0; i < 100; ++i) {
    t[static_cast<std::size_t>(2 * i)] = static_cast<char>('0' + i / 10);
    t[static_cast<std::size_t>(2 * i + 1)] = static_cast<char>('0' + i % 10);
  }
  return t;
}();
const char* const kDigitPairs = kDigitPairsTable.data();

}  // namespace

// Hand-rolled for the common range because it is ~4x faster than to_chars with a precision, and
// a report formats a few hundred thousand numbers within a command budgeted at ~20 ms.
char* format_number(char* out, double v) {
  if (!std::isfinite(v)) {
    std::memcpy(out, "null", 4);
    return out + 4;
  }
  if (v == 0) {
    *out = '0';
    return out + 1;
  }
  if (v < 0) {
    *out++ = '-';
    v = -v;
  }
  if (v < 1e-4 || v >= 1e9) return std::to_chars(out, out + 15, v, std::chars_format::general, 6).ptr;
  int e = v >= 1 ? 0 : -4;  // decimal exponent: 10^e <= v < 10^(e+1)
  while (e < 8 && v >= pow10(e + 1)) ++e;
  const int shift = 5 - e;  // six digits in total
  // v > 0 here, so adding 0.5 and truncating rounds (llround is an out-of-line libm call).
  auto m = static_cast<std::int64_t>((shift >= 0 ? v * pow10(shift) : v / pow10(-shift)) + 0.5);
  if (m >= 1000000) {  // rounded up to the next decade: 9.999996 -> 10.0000
    m /= 10;
    ++e;
  }
  char d[6];  // two digits at a time from a table: fewer divisions
  const auto m32 = static_cast<std::uint32_t>(m);
  std::memcpy(d, kDigitPairs + 2 * (m32 / 10000), 2);
  std::memcpy(d + 2, kDigitPairs + 2 * (m32 / 100 % 100), 2);
  std::memcpy(d + 4, kDigitPairs + 2 * (m32 % 100), 2);
  int last = 5;  // last significant digit after trailing zeros are stripped
  while (last > 0 && d[last] == '0') --last;
  if (e >= 5) {
    std::memcpy(out, d, 6);
    out += 6;
    for (int i = 5; i < e; ++i) *out++ = '0';
  } else if (e >= 0) {
    std::memcpy(out, d, static_cast<std::size_t>(e + 1));
    out += e + 1;
    if (last > e) {
      *out++ = '.';
      for (int i = e + 1; i <= last; ++i) *out++ = d[i];
    }
  } else {
    *out++ = '0';
    *out++ = '.';
    for (int i = -1; i > e; --i) *out++ = '0';
    for (int i = 0; i <= last; ++i) *out++ = d[i];
  }
  return out;
}

Decimated decimate(std::span<const double> x, std::span<const double> y, std::size_t max_buckets, Thin thin, bool x_log,
                   bool y_log) {
  const std::size_t n = std::min(x.size(), y.size());
  const std::size_t buckets = std::max<std::size_t>(max_buckets, 1);
  // NaN compares false, so a NaN is not "dropped" but becomes a gap below.
  auto dropped = [&](std::size_t i) { return (x_log && x[i] <= 0) || (y_log && y[i] <= 0); };
  auto finite = [&](std::size_t i) { return std::isfinite(x[i]) && std::isfinite(y[i]); };
  Decimated out;

  if (thin == Thin::points) {
    const bool thin_grid = n > 2 * buckets;
    out.x.reserve(thin_grid ? 2 * buckets : n);
    out.y.reserve(out.x.capacity());
    if (!thin_grid) {
      for (std::size_t i = 0; i < n; ++i) {
        if (!dropped(i) && finite(i)) out.x.push_back(x[i]), out.y.push_back(y[i]);
      }
      return out;
    }
    // Cells are laid out in axis space, so a log axis gets log-spaced cells.
    auto ax = [&](std::size_t i) { return x_log ? std::log10(x[i]) : x[i]; };
    auto ay = [&](std::size_t i) { return y_log ? std::log10(y[i]) : y[i]; };
    double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
    for (std::size_t i = 0; i < n; ++i) {
      if (dropped(i) || !finite(i)) continue;
      x0 = std::min(x0, ax(i)), x1 = std::max(x1, ax(i));
      y0 = std::min(y0, ay(i)), y1 = std::max(y1, ay(i));
    }
    constexpr int kCells = 256;
    const double sx = x1 > x0 ? (kCells - 1e-9) / (x1 - x0) : 0;
    const double sy = y1 > y0 ? (kCells - 1e-9) / (y1 - y0) : 0;
    std::vector<std::uint8_t> taken(kCells * kCells, 0);
    for (std::size_t i = 0; i < n; ++i) {
      if (dropped(i) || !finite(i)) continue;
      const auto cx = static_cast<int>((ax(i) - x0) * sx);
      const auto cy = static_cast<int>((ay(i) - y0) * sy);
      auto& cell = taken[static_cast<std::size_t>(cy * kCells + cx)];
      if (cell) continue;
      cell = 1;
      out.x.push_back(x[i]), out.y.push_back(y[i]);
    }
    return out;
  }

  const std::span<const double> column = y.first(n);
  DecimatedShared shared = decimate_shared(x.first(n), std::span(&column, 1), max_buckets, x_log, y_log);
  out.x = std::move(shared.x);
  out.y = std::move(shared.y.front());
  return out;
}

DecimatedShared decimate_shared(std::span<const double> x, std::span<const std::span<const double>> ys, std::size_t max_buckets,
                                bool x_log, bool y_log) {
  std::size_t n = x.size();
  for (const auto& y : ys) n = std::min(n, y.size());
  const std::size_t columns = std::max<std::size_t>(ys.size(), 1);
  const bool drop_y = y_log && ys.size() == 1;
  // NaN compares false, so a NaN is not "dropped" but becomes a gap below.
  auto dropped = [&](std::size_t i) { return (x_log && x[i] <= 0) || (drop_y && ys[0][i] <= 0); };
  std::size_t drawable = 0;
  for (std::size_t i = 0; i < n; ++i) drawable += dropped(i) ? 0 : 1;
  auto decimator = MinMaxDecimator::for_length(drawable, std::max<std::size_t>(max_buckets, 1), columns);
  std::vector<double> row(columns, std::numeric_limits<double>::quiet_NaN());
  for (std::size_t i = 0; i < n; ++i) {
    if (dropped(i)) continue;
    for (std::size_t c = 0; c < ys.size(); ++c)
      row[c] = y_log && ys[c][i] <= 0 ? std::numeric_limits<double>::quiet_NaN() : ys[c][i];
    decimator.add(x[i], row);
  }
  DecimatedShared kept;
  decimator.take(kept.x, kept.y);
  kept.y.resize(ys.size());

  // A row inside an equal-y run of every series, with x in order, adds nothing to the drawn lines.
  const std::size_t m = kept.x.size();
  auto flat = [&](std::size_t i) {
    if (i == 0 || i + 1 >= m || !(kept.x[i - 1] <= kept.x[i] && kept.x[i] <= kept.x[i + 1])) return false;
    for (const auto& y : kept.y)
      if (!(y[i - 1] == y[i] && y[i] == y[i + 1])) return false;
    return true;
  };
  DecimatedShared out;
  out.y.resize(ys.size());
  out.x.reserve(m);
  for (auto& y : out.y) y.reserve(m);
  for (std::size_t i = 0; i < m; ++i) {
    if (flat(i)) continue;
    out.x.push_back(kept.x[i]);
    for (std::size_t c = 0; c < ys.size(); ++c) out.y[c].push_back(kept.y[c][i]);
  }
  return out;
}

void append_numbers(std::string& out, std::span<const double> v) {
  const std::size_t start = out.size();
  out.resize(start + 2 + v.size() * 17);  // 16 chars per number at most, plus a comma
  char* p = out.data() + start;
  *p++ = '[';
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (i > 0) *p++ = ',';
    p = format_number(p, v[i]);
  }
  *p++ = ']';
  out.resize(static_cast<std::size_t>(p - out.data()));
}

std::string html_escape(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&#39;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string json_string(std::string_view text) {
  const std::string dumped = nlohmann::json(std::string(text)).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  std::string out;
  out.reserve(dumped.size());
  for (char c : dumped) {
    switch (c) {  // inside a JSON string these can only be literal characters
      case '<': out += "\\u003c"; break;
      case '>': out += "\\u003e"; break;
      case '&': out += "\\u0026"; break;
      default: out += c;
    }
  }
  return out;
}

}  // namespace hil::report::detail
