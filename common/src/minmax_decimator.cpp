#include "hil/minmax_decimator.hpp"

#include <cmath>
#include <utility>

namespace hil {

void MinMaxDecimator::add(double t, double value) {
  if (!std::isfinite(value)) return;
  if (count_ == 0) buckets_.push_back({t, value, t, value});
  Bucket& b = buckets_.back();
  if (value < b.v_min) b.v_min = value, b.t_min = t;
  if (value > b.v_max) b.v_max = value, b.t_max = t;
  if (++count_ == per_bucket_) {
    count_ = 0;
    if (buckets_.size() >= 2 * max_buckets_) merge();
  }
}

void MinMaxDecimator::merge() {
  std::size_t out = 0;
  for (std::size_t i = 0; i + 1 < buckets_.size(); i += 2) {
    Bucket a = buckets_[i];
    const Bucket& b = buckets_[i + 1];
    if (b.v_min < a.v_min) a.v_min = b.v_min, a.t_min = b.t_min;
    if (b.v_max > a.v_max) a.v_max = b.v_max, a.t_max = b.t_max;
    buckets_[out++] = a;
  }
  if (buckets_.size() % 2 == 1) buckets_[out++] = buckets_.back();
  buckets_.resize(out);
  per_bucket_ *= 2;
}

void MinMaxDecimator::take(std::vector<double>& t_out, std::vector<double>& value_out) const {
  t_out.clear();
  value_out.clear();
  t_out.reserve(2 * buckets_.size());
  value_out.reserve(2 * buckets_.size());
  for (const auto& b : buckets_) {
    const bool min_first = b.t_min <= b.t_max;
    t_out.push_back(min_first ? b.t_min : b.t_max);
    value_out.push_back(min_first ? b.v_min : b.v_max);
    if (b.t_min != b.t_max) {
      t_out.push_back(min_first ? b.t_max : b.t_min);
      value_out.push_back(min_first ? b.v_max : b.v_min);
    }
  }
}

}  // namespace hil
