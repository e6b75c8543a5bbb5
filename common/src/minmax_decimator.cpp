#include "hil/minmax_decimator.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace hil {

MinMaxDecimator MinMaxDecimator::for_length(std::size_t samples, std::size_t buckets) {
  MinMaxDecimator d(buckets);
  d.length_ = std::max<std::size_t>(samples, 1);
  d.fixed_buckets_ = d.length_ <= 2 * d.max_buckets_ ? d.length_ : d.max_buckets_;
  return d;
}

void MinMaxDecimator::add(double t, double value) {
  const Sample s{added_++, t, value};
  const bool finite = std::isfinite(t) && std::isfinite(value);
  if (length_ == 0) {  // streamed
    if (!finite) return;
    if (count_ == 0) {
      if (buckets_.empty()) buckets_.reserve(2 * max_buckets_);
      buckets_.push_back({s, s});
    }
  } else {
    if (s.i == 0) first_ = s;
    last_ = s;
    if (s.i == next_start_) {
      if (buckets_.empty()) buckets_.reserve(fixed_buckets_);
      buckets_.push_back({});
      next_start_ =
          buckets_.size() < fixed_buckets_ ? buckets_.size() * length_ / fixed_buckets_ : std::numeric_limits<std::size_t>::max();
    }
    if (!finite) {
      const std::size_t k = buckets_.size() - 1;
      if (gaps_.empty() || gaps_.back().first != k) gaps_.emplace_back(k, s);
      return;
    }
  }
  Bucket& b = buckets_.back();
  if (b.min.i == kNone || value < b.min.v) b.min = s;
  if (b.max.i == kNone || value > b.max.v) b.max = s;
  if (length_ == 0 && ++count_ == per_bucket_) {
    count_ = 0;
    if (buckets_.size() >= 2 * max_buckets_) merge();
  }
}

void MinMaxDecimator::merge() {
  std::size_t out = 0;
  for (std::size_t i = 0; i + 1 < buckets_.size(); i += 2) {
    Bucket a = buckets_[i];
    const Bucket& b = buckets_[i + 1];
    if (b.min.v < a.min.v) a.min = b.min;
    if (b.max.v > a.max.v) a.max = b.max;
    buckets_[out++] = a;
  }
  if (buckets_.size() % 2 == 1) buckets_[out++] = buckets_.back();
  buckets_.resize(out);
  per_bucket_ *= 2;
}

void MinMaxDecimator::take(std::vector<double>& t_out, std::vector<double>& value_out) const {
  t_out.clear();
  value_out.clear();
  t_out.reserve(2 * buckets_.size() + 2);
  value_out.reserve(t_out.capacity());
  bool line_open = false;  // a gap marker only follows a drawn point
  auto emit = [&](const Sample& s) {
    if (std::isfinite(s.t) && std::isfinite(s.v)) {
      t_out.push_back(s.t), value_out.push_back(s.v);
      line_open = true;
    } else if (line_open) {
      t_out.push_back(std::isfinite(s.t) ? s.t : t_out.back());
      value_out.push_back(std::numeric_limits<double>::quiet_NaN());
      line_open = false;
    }
  };
  const bool ends = length_ != 0;
  std::size_t g = 0;  // the next gap
  for (std::size_t k = 0; k < buckets_.size(); ++k) {
    const Bucket& b = buckets_[k];
    const bool gap = g < gaps_.size() && gaps_[g].first == k;
    std::array<Sample, 5> picks = {ends && k == 0 ? first_ : Sample{}, b.min, b.max, gap ? gaps_[g++].second : Sample{},
                                   ends && k + 1 == buckets_.size() ? last_ : Sample{}};
    std::sort(picks.begin(), picks.end(), [](const Sample& a, const Sample& c) { return a.i < c.i; });
    for (std::size_t p = 0; p < picks.size() && picks[p].i != kNone; ++p) {
      if (p == 0 || picks[p].i != picks[p - 1].i) emit(picks[p]);
    }
  }
  if (!value_out.empty() && std::isnan(value_out.back())) t_out.pop_back(), value_out.pop_back();
}

}  // namespace hil
