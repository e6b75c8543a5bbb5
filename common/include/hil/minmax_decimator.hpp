// Min/max decimation of a series that arrives one sample at a time (a simulated run, a replayed
// measurement), in bounded memory whatever its length, for plots: each bucket keeps its smallest
// and its largest value with their times, so spikes survive; when there are 2 x max_buckets
// buckets, neighbours merge pairwise and each bucket covers twice as many samples. Non-finite
// values are skipped. The report writer thins again for drawing (report/encode.cpp, with gaps and
// log axes). Not for the real-time path: add() may allocate.
#pragma once

#include <cstddef>
#include <vector>

namespace hil {

class MinMaxDecimator {
 public:
  explicit MinMaxDecimator(std::size_t max_buckets) : max_buckets_(max_buckets < 1 ? 1 : max_buckets) {}

  void add(double t, double value);
  // The kept points in time order: between max_buckets and 2 x max_buckets buckets (fewer for a
  // short series: then every sample), at most two points each (one when min and max coincide).
  void take(std::vector<double>& t_out, std::vector<double>& value_out) const;

 private:
  struct Bucket {
    double t_min, v_min, t_max, v_max;
  };
  void merge();
  std::size_t max_buckets_;
  std::vector<Bucket> buckets_;
  std::size_t per_bucket_ = 1, count_ = 0;  // samples per bucket, samples in the last bucket
};

}  // namespace hil
