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

inline std::string join(const std::vector<std::string>& parts, const std::string& sep) {
  std::string out;
  for (const auto& p : parts) out += (out.empty() ? "" : sep) + p;
  return out;
}

}  // namespace hil::analysis::text
