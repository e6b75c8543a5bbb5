#include "hil/minmax_decimator.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace hil {

MinMaxDecimator::MinMaxDecimator(std::size_t max_buckets, std::size_t columns)
    : columns_(std::max<std::size_t>(columns, 1)), max_buckets_(std::max<std::size_t>(max_buckets, 1)) {}

MinMaxDecimator MinMaxDecimator::for_length(std::size_t samples, std::size_t buckets, std::size_t columns) {
  MinMaxDecimator d(buckets, columns);
  d.length_ = std::max<std::size_t>(samples, 1);
  d.fixed_buckets_ = d.length_ <= 2 * d.max_buckets_ ? d.length_ : d.max_buckets_;
  return d;
}

void MinMaxDecimator::open_bucket() {
  if (buckets_.empty()) {
    const std::size_t n = length_ == 0 ? 2 * max_buckets_ : fixed_buckets_;
    buckets_.reserve(n);
    extremes_.reserve(n * columns_);
  }
  buckets_.push_back({});
  extremes_.resize(extremes_.size() + columns_);
}

void MinMaxDecimator::add(double t, std::span<const double> values) {
  const std::size_t i = added_++;
  if (length_ == 0) {
    if (count_ == 0) open_bucket();
  } else if (i == next_start_) {
    open_bucket();
    next_start_ =
        buckets_.size() < fixed_buckets_ ? buckets_.size() * length_ / fixed_buckets_ : std::numeric_limits<std::size_t>::max();
  }
  Bucket& b = buckets_.back();
  Extremes* e = extremes_.data() + (buckets_.size() - 1) * columns_;
  const bool t_finite = std::isfinite(t);
  if (t_finite) {
    if (!b.has_t) b.t_first = t, b.has_t = true;
    b.t_last = t;
  }
  for (std::size_t c = 0; c < columns_; ++c) {
    const double v = c < values.size() ? values[c] : std::numeric_limits<double>::quiet_NaN();
    Extremes& x = e[c];
    if (!t_finite || !std::isfinite(v)) {
      if (x.gap == kNone) x.gap = i;
      if (b.gap == kNone) b.gap = i, b.t_gap = t;
      continue;
    }
    if (x.min.i == kNone || v < x.min.v) x.min = {i, v};
    if (x.max.i == kNone || v > x.max.v) x.max = {i, v};
  }
  if (length_ == 0 && ++count_ == per_bucket_) {
    count_ = 0;
    if (buckets_.size() >= 2 * max_buckets_) merge();
  }
}

void MinMaxDecimator::merge() {
  std::size_t out = 0;
  for (std::size_t k = 0; k + 1 < buckets_.size(); k += 2, ++out) {
    Bucket a = buckets_[k];
    const Bucket& b = buckets_[k + 1];
    if (b.has_t) {
      if (!a.has_t) a.t_first = b.t_first, a.has_t = true;
      a.t_last = b.t_last;
    }
    if (a.gap == kNone) a.gap = b.gap, a.t_gap = b.t_gap;
    buckets_[out] = a;
    for (std::size_t c = 0; c < columns_; ++c) {
      Extremes x = extremes_[k * columns_ + c];
      const Extremes& y = extremes_[(k + 1) * columns_ + c];
      if (y.min.i != kNone && (x.min.i == kNone || y.min.v < x.min.v)) x.min = y.min;
      if (y.max.i != kNone && (x.max.i == kNone || y.max.v > x.max.v)) x.max = y.max;
      if (x.gap == kNone) x.gap = y.gap;
      extremes_[out * columns_ + c] = x;
    }
  }
  if (buckets_.size() % 2 == 1) {
    buckets_[out] = buckets_.back();
    std::copy_n(extremes_.end() - static_cast<long>(columns_), columns_, extremes_.begin() + static_cast<long>(out * columns_));
    ++out;
  }
  buckets_.resize(out);
  extremes_.resize(out * columns_);
  per_bucket_ *= 2;
}

void MinMaxDecimator::take(std::vector<double>& t_out, std::vector<std::vector<double>>& values_out) const {
  constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
  t_out.clear();
  values_out.assign(columns_, {});
  const std::size_t cap = 3 * buckets_.size();
  t_out.reserve(cap);
  for (auto& v : values_out) v.reserve(cap);

  // Each column's entries in one bucket, in input order: its extremes and its gap marker.
  struct Entry {
    std::size_t i;
    double v;
  };
  std::vector<std::array<Entry, 3>> entries(columns_);
  std::vector<std::size_t> counts(columns_);
  bool last_all_nan = true;  // so leading all-NaN rows are left out
  auto emit = [&](double t, std::size_t slot) {
    bool all_nan = true;
    for (std::size_t c = 0; c < columns_ && all_nan; ++c) all_nan = std::isnan(entries[c][std::min(slot, counts[c] - 1)].v);
    if (all_nan && last_all_nan) return;  // once per run of gaps
    last_all_nan = all_nan;
    t_out.push_back(t);
    for (std::size_t c = 0; c < columns_; ++c) values_out[c].push_back(entries[c][std::min(slot, counts[c] - 1)].v);
  };

  for (std::size_t k = 0; k < buckets_.size(); ++k) {
    const Bucket& b = buckets_[k];
    std::size_t most = 1;
    for (std::size_t c = 0; c < columns_; ++c) {
      const Extremes& x = extremes_[k * columns_ + c];
      auto& list = entries[c];
      std::size_t n = 0;
      if (x.min.i != kNone) list[n++] = {x.min.i, x.min.v};
      if (x.max.i != kNone && x.max.i != x.min.i) list[n++] = {x.max.i, x.max.v};
      if (x.gap != kNone) list[n++] = {x.gap, kNan};
      if (n == 0) list[n++] = {0, kNan};  // unreachable: every row gives each column one
      std::sort(list.begin(), list.begin() + static_cast<long>(n), [](const Entry& a, const Entry& e) { return a.i < e.i; });
      counts[c] = n;
      most = std::max(most, n);
    }
    if (!b.has_t) {  // every row of the bucket is a gap
      if (!t_out.empty()) emit(t_out.back(), 0);
      continue;
    }
    // The shared rows: first and last time, a gap row between; more rows at the same time only
    // where the bucket's times do not spread (a column has more entries than distinct times).
    const std::size_t spread = (b.t_first != b.t_last ? 2 : 1) + (b.gap != kNone ? 1 : 0);
    const std::size_t rows = std::max(spread, most);
    if (rows == 1) {
      emit(b.t_first, 0);
    } else if (rows == 2) {
      emit(b.t_first, 0);
      emit(b.t_last, 1);
    } else {
      const bool inside =
          std::isfinite(b.t_gap) && std::min(b.t_first, b.t_last) < b.t_gap && b.t_gap < std::max(b.t_first, b.t_last);
      emit(b.t_first, 0);
      emit(inside ? b.t_gap : 0.5 * (b.t_first + b.t_last), 1);
      emit(b.t_last, 2);
    }
  }
  if (!t_out.empty() && last_all_nan) {  // never a trailing gap marker
    t_out.pop_back();
    for (auto& v : values_out) v.pop_back();
  }
}

void MinMaxDecimator::take(std::vector<double>& t_out, std::vector<double>& value_out) const {
  std::vector<std::vector<double>> values;
  take(t_out, values);
  value_out = std::move(values.front());
}

}  // namespace hil
