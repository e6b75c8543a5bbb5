// Small text helpers for the workbench's console output and reports (internal).
#pragma once

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

namespace hil::analysis::text {

// `v` with `digits` significant digits ("%.*g"); "n/a" for non-finite values.
inline std::string num(double v, int digits = 4) {
  if (!std::isfinite(v)) return "n/a";
  char b[48];
  std::snprintf(b, sizeof b, "%.*g", digits, v);
  return b;
}

// Fixed decimals ("%.*f").
inline std::string fixed(double v, int decimals) {
  if (!std::isfinite(v)) return "n/a";
  char b[48];
  std::snprintf(b, sizeof b, "%.*f", decimals, v);
  return b;
}

// An instant of a file's clock in a sentence, in seconds: three significant digits below 100 s
// ("12.3"), tenths above ("3599.8", "1764250012.3"). "%.3g" alone made an hour's 3599.8 s
// "3.6e+03" and every instant of a logger's Unix-epoch clock "1.76e+09".
inline std::string instant(double t_s) {
  if (!std::isfinite(t_s)) return "n/a";
  char b[48];
  std::snprintf(b, sizeof b, std::abs(t_s) < 100 ? "%.3g" : "%.1f", t_s);
  return b;
}

inline std::string join(const std::vector<std::string>& parts, const std::string& sep) {
  std::string out;
  for (const auto& p : parts) out += (out.empty() ? "" : sep) + p;
  return out;
}

}  // namespace hil::analysis::text
