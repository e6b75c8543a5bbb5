// Percentiles of a sample, printed as one line a person and a script can read.
#pragma once

#include <algorithm>
#include <cstdio>
#include <vector>

namespace hil::drv::bench {

inline void print_stats(const char* name, std::vector<double> us) {
  if (us.empty()) {
    std::printf("%-40s n=0\n", name);
    return;
  }
  std::sort(us.begin(), us.end());
  const auto at = [&](double q) { return us[static_cast<std::size_t>(q * (us.size() - 1))]; };
  std::printf("%-40s n=%zu p50=%.1f us p99=%.1f us max=%.1f us\n", name, us.size(), at(0.5), at(0.99), us.back());
  std::fflush(stdout);
}

}  // namespace hil::drv::bench
