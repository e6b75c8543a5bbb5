// The min/max decimator. Streamed: bounded output whatever the length, every spike kept, a short
// series kept whole, points in time order, non-finite values skipped. For a known length: each
// index bucket's extremes, the ends, one gap marker per run of non-finite samples.
#include "hil/minmax_decimator.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace {

TEST(MinMaxDecimator, AShortSeriesIsKeptWhole) {
  hil::MinMaxDecimator d(100);
  for (int i = 0; i < 150; ++i) d.add(0.1 * i, i % 3);
  std::vector<double> t, v;
  d.take(t, v);
  ASSERT_EQ(t.size(), 150u);
  EXPECT_DOUBLE_EQ(t[149], 14.9);
  EXPECT_EQ(v[2], 2);
}

TEST(MinMaxDecimator, ALongSeriesStaysBoundedKeepsEverySpikeAndItsOrder) {
  const std::size_t buckets = 50, n = 1'000'003;
  hil::MinMaxDecimator d(buckets);
  std::vector<std::size_t> spikes;
  for (std::size_t i = 0; i < n; ++i) {
    double v = std::sin(1e-4 * static_cast<double>(i));
    if (i % 99'991 == 7) v = (spikes.size() % 2 == 0 ? 10.0 : -10.0), spikes.push_back(i);
    d.add(1e-3 * static_cast<double>(i), v);
  }
  std::vector<double> t, v;
  d.take(t, v);
  EXPECT_GE(t.size(), buckets);
  EXPECT_LE(t.size(), 4 * buckets);
  EXPECT_TRUE(std::is_sorted(t.begin(), t.end()));
  for (std::size_t i : spikes) {
    const double ti = 1e-3 * static_cast<double>(i);
    const auto it = std::find(t.begin(), t.end(), ti);
    ASSERT_NE(it, t.end()) << "spike at " << ti << " s lost";
    EXPECT_EQ(std::abs(v[static_cast<std::size_t>(it - t.begin())]), 10.0);
  }
  EXPECT_DOUBLE_EQ(*std::max_element(v.begin(), v.end()), 10.0);
  EXPECT_DOUBLE_EQ(*std::min_element(v.begin(), v.end()), -10.0);
}

TEST(MinMaxDecimator, NonFiniteValuesAreSkipped) {
  hil::MinMaxDecimator d(10);
  d.add(0, 1);
  d.add(1, NAN);
  d.add(2, INFINITY);
  d.add(3, 2);
  std::vector<double> t, v;
  d.take(t, v);
  EXPECT_EQ(t, (std::vector<double>{0, 3}));
  EXPECT_EQ(v, (std::vector<double>{1, 2}));
}

TEST(MinMaxDecimator, ForALengthKeepsEveryIndexBucketsExtremesAndTheEnds) {
  const std::size_t n = 10007, buckets = 40;
  auto d = hil::MinMaxDecimator::for_length(n, buckets);
  std::vector<double> y(n);
  for (std::size_t i = 0; i < n; ++i) {
    y[i] = std::sin(0.013 * static_cast<double>(i)) + 0.3 * std::sin(1.7 * static_cast<double>(i));
    d.add(static_cast<double>(i), y[i]);
  }
  std::vector<double> t, v;
  d.take(t, v);
  EXPECT_LE(t.size(), 2 * buckets + 2);
  EXPECT_EQ(t.front(), 0.0);
  EXPECT_EQ(t.back(), static_cast<double>(n - 1));
  EXPECT_TRUE(std::is_sorted(t.begin(), t.end()));
  for (std::size_t b = 0; b < buckets; ++b) {
    const auto lo = y.begin() + static_cast<long>(b * n / buckets), hi = y.begin() + static_cast<long>((b + 1) * n / buckets);
    const auto [mn, mx] = std::minmax_element(lo, hi);
    for (const auto it : {mn, mx}) {
      const double ti = static_cast<double>(it - y.begin());
      const auto at = std::find(t.begin(), t.end(), ti);
      ASSERT_NE(at, t.end()) << "bucket " << b << " lost its extreme at " << ti;
      EXPECT_EQ(v[static_cast<std::size_t>(at - t.begin())], *it);
    }
  }
}

TEST(MinMaxDecimator, ForALengthMarksEachRunOfGapsOnceNeverAtTheEnds) {
  auto d = hil::MinMaxDecimator::for_length(9, 100);
  const double nan = std::nan(""), inf = std::numeric_limits<double>::infinity();
  for (const double y : {nan, 1.0, 2.0, nan, inf, 3.0, 4.0, nan, nan}) d.add(0, y);
  std::vector<double> t, v;
  d.take(t, v);
  ASSERT_EQ(v.size(), 5u);
  EXPECT_EQ(v[0], 1);
  EXPECT_EQ(v[1], 2);
  EXPECT_TRUE(std::isnan(v[2]));
  EXPECT_EQ(v[3], 3);
  EXPECT_EQ(v[4], 4);
}

}  // namespace
