// Min/max decimation of a series that arrives one sample at a time, in bounded memory whatever its
// length, for plots: each bucket keeps its smallest and its largest value (in input order), so
// spikes survive. The one decimator of the tree, in two modes:
//   streamed (a simulated run, a replayed measurement: the length is not known in advance): when
//     there are 2 x max_buckets buckets, neighbours merge pairwise and each bucket covers twice as
//     many samples; non-finite values are skipped;
//   for_length (the report writer, which holds the whole series): bucket b covers samples
//     [b n / B, (b + 1) n / B) of the n announced, the first and last samples are kept so the line
//     spans the whole range, and a non-finite sample becomes a gap marker (value NaN) where the
//     line must break: one per run of gaps, none leading or trailing.
// Not for the real-time path: add() may allocate.
#pragma once

#include <cstddef>
#include <utility>
#include <vector>

namespace hil {

class MinMaxDecimator {
 public:
  explicit MinMaxDecimator(std::size_t max_buckets) : max_buckets_(max_buckets < 1 ? 1 : max_buckets) {}
  // Fixed index buckets over `samples` samples, at most `buckets` of them (every sample its own
  // bucket when samples <= 2 x buckets), with the ends and gap markers kept.
  static MinMaxDecimator for_length(std::size_t samples, std::size_t buckets);

  void add(double t, double value);
  // The kept points in input order: at most two per bucket plus, for_length, the ends and gap
  // markers. Streamed: between max_buckets and 2 x max_buckets buckets (fewer for a short series:
  // then every sample).
  void take(std::vector<double>& t_out, std::vector<double>& value_out) const;

 private:
  static constexpr std::size_t kNone = static_cast<std::size_t>(-1);
  struct Sample {
    std::size_t i = kNone;  // index in the input; kNone: no such sample
    double t = 0, v = 0;
  };
  struct Bucket {
    Sample min, max;
  };
  void merge();
  std::size_t max_buckets_;
  std::vector<Bucket> buckets_;
  // for_length: (bucket, its first non-finite sample), in bucket order. Apart from the buckets,
  // which stay small: add() is a report's per-sample cost.
  std::vector<std::pair<std::size_t, Sample>> gaps_;
  std::size_t per_bucket_ = 1, count_ = 0;  // streamed: samples per bucket, samples in the last bucket
  std::size_t added_ = 0;                   // samples seen
  // for_length: the announced length (0: streamed), the bucket count, the next bucket's first index.
  std::size_t length_ = 0, fixed_buckets_ = 0, next_start_ = 0;
  Sample first_, last_;
};

}  // namespace hil
