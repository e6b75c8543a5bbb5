#include "hil/bench/rt/loop_stats.hpp"

#include <algorithm>
#include <bit>
#include <cmath>

namespace hil::bench {

nlohmann::json TimingSummary::to_json() const {
  auto r = [](double v) { return std::round(v * 100) / 100; };  // 10 ns is plenty
  return {{"count", count},      {"min_us", r(min_us)},    {"mean_us", r(mean_us)}, {"p50_us", r(p50_us)},
          {"p99_us", r(p99_us)}, {"p99_9_us", r(p999_us)}, {"max_us", r(max_us)}};
}

int LatencyHistogram::bucket_of(std::uint64_t ns) noexcept {
  if (ns < kSub) return static_cast<int>(ns);
  const int msb = 63 - std::countl_zero(ns);  // >= 6
  const int shift = msb - 6;
  return (shift + 1) * kSub + static_cast<int>((ns >> shift) - kSub);
}

std::uint64_t LatencyHistogram::upper_edge(int bucket) noexcept {
  if (bucket < kSub) return static_cast<std::uint64_t>(bucket);
  const int shift = bucket / kSub - 1;
  const std::uint64_t sub = static_cast<std::uint64_t>(bucket % kSub + kSub);
  return ((sub + 1) << shift) - 1;
}

void LatencyHistogram::add(std::chrono::nanoseconds d) noexcept {
  const std::int64_t ns = std::max<std::int64_t>(0, d.count());
  auto& c = counts_[static_cast<std::size_t>(bucket_of(static_cast<std::uint64_t>(ns)))];
  c.store(c.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
  sum_ns_.store(sum_ns_.load(std::memory_order_relaxed) + ns, std::memory_order_relaxed);
  if (ns < min_ns_.load(std::memory_order_relaxed)) min_ns_.store(ns, std::memory_order_relaxed);
  if (ns > max_ns_.load(std::memory_order_relaxed)) max_ns_.store(ns, std::memory_order_relaxed);
  count_.store(count_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
}

TimingSummary LatencyHistogram::summary() const noexcept {
  TimingSummary s;
  s.count = count_.load(std::memory_order_acquire);
  if (s.count == 0) return s;
  const double max_ns = static_cast<double>(max_ns_.load(std::memory_order_relaxed));
  s.min_us = static_cast<double>(min_ns_.load(std::memory_order_relaxed)) / 1e3;
  s.max_us = max_ns / 1e3;
  s.mean_us = static_cast<double>(sum_ns_.load(std::memory_order_relaxed)) / static_cast<double>(s.count) / 1e3;
  // The counts may run ahead of count_ while the writer works: rank against what is there.
  std::int64_t total = 0;
  for (const auto& c : counts_) total += c.load(std::memory_order_relaxed);
  auto percentile = [&](double q) {
    const auto rank = static_cast<std::int64_t>(std::ceil(q * static_cast<double>(total)));
    std::int64_t seen = 0;
    for (int b = 0; b < kBuckets; ++b) {
      seen += counts_[static_cast<std::size_t>(b)].load(std::memory_order_relaxed);
      if (seen >= std::max<std::int64_t>(rank, 1)) return std::min(static_cast<double>(upper_edge(b)), max_ns) / 1e3;
    }
    return max_ns / 1e3;
  };
  s.p50_us = percentile(0.5);
  s.p99_us = percentile(0.99);
  s.p999_us = percentile(0.999);
  return s;
}

}  // namespace hil::bench
