// The min/max decimator. All columns share their rows; each bucket is written at its first and
// last time with each column's min and max in input order, so every bucket's extremes survive; a
// short series is kept whole; streamed output is bounded and its times depend only on the row
// count; non-finite values are gaps, one all-NaN row per run, never at the ends.
#include "hil/minmax_decimator.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

// Column c's signal at row i: different shapes, so the columns' extremes fall on different rows.
double signal(std::size_t c, std::size_t i) {
  const double x = static_cast<double>(i);
  switch (c) {
    case 0: return std::sin(0.013 * x) + 0.3 * std::sin(1.7 * x);
    case 1: return (i % 977 == 13 ? 25.0 : 0.0) + std::cos(0.002 * x);  // spikes
    default: return std::floor(x / 1500);                               // steps
  }
}

// Does column `v` hold `value` on a row with a time in [t0, t1]?
bool holds(const std::vector<double>& t, const std::vector<double>& v, double t0, double t1, double value) {
  for (std::size_t k = 0; k < t.size(); ++k) {
    if (t[k] >= t0 && t[k] <= t1 && v[k] == value) return true;
  }
  return false;
}

TEST(MinMaxDecimator, AShortSeriesIsKeptWhole) {
  for (const bool streamed : {true, false}) {
    auto d = streamed ? hil::MinMaxDecimator(100, 2) : hil::MinMaxDecimator::for_length(200, 100, 2);
    for (int i = 0; i < 200; ++i) d.add(0.1 * i, std::array<double, 2>{static_cast<double>(i % 3), -static_cast<double>(i)});
    std::vector<double> t;
    std::vector<std::vector<double>> v;
    d.take(t, v);
    ASSERT_EQ(t.size(), 200u) << (streamed ? "streamed" : "for_length");
    ASSERT_EQ(v.size(), 2u);
    for (std::size_t i = 0; i < 200; ++i) {
      EXPECT_DOUBLE_EQ(t[i], 0.1 * static_cast<double>(i));
      EXPECT_EQ(v[0][i], static_cast<double>(i % 3));
      EXPECT_EQ(v[1][i], -static_cast<double>(i));
    }
  }
}

TEST(MinMaxDecimator, ForALengthKeepsEveryBucketsExtremesOfEveryColumnOnSharedRows) {
  const std::size_t n = 10007, buckets = 40, columns = 3;
  auto d = hil::MinMaxDecimator::for_length(n, buckets, columns);
  std::vector<std::vector<double>> y(columns, std::vector<double>(n));
  for (std::size_t i = 0; i < n; ++i) {
    std::array<double, columns> row{};
    for (std::size_t c = 0; c < columns; ++c) row[c] = y[c][i] = signal(c, i);
    d.add(static_cast<double>(i), row);
  }
  std::vector<double> t;
  std::vector<std::vector<double>> v;
  d.take(t, v);
  ASSERT_EQ(v.size(), columns);
  for (const auto& col : v) EXPECT_EQ(col.size(), t.size()) << "a value of every column on every row";
  EXPECT_EQ(t.size(), 2 * buckets) << "two rows per bucket, whatever the number of columns";
  EXPECT_EQ(t.front(), 0.0);
  EXPECT_EQ(t.back(), static_cast<double>(n - 1));
  EXPECT_TRUE(std::is_sorted(t.begin(), t.end()));
  for (std::size_t b = 0; b < buckets; ++b) {
    const std::size_t lo = b * n / buckets, hi = (b + 1) * n / buckets;
    for (std::size_t c = 0; c < columns; ++c) {
      const auto [mn, mx] = std::minmax_element(y[c].begin() + static_cast<long>(lo), y[c].begin() + static_cast<long>(hi));
      // On the bucket's own rows: at its first and last time.
      EXPECT_TRUE(holds(t, v[c], static_cast<double>(lo), static_cast<double>(hi - 1), *mn)) << "bucket " << b << " column " << c;
      EXPECT_TRUE(holds(t, v[c], static_cast<double>(lo), static_cast<double>(hi - 1), *mx)) << "bucket " << b << " column " << c;
    }
  }
}

TEST(MinMaxDecimator, StreamedStaysBoundedKeepsEverySpikeAndSharesItsTimes) {
  const std::size_t buckets = 50, n = 1'000'003;
  hil::MinMaxDecimator both(buckets, 2), alone(buckets);
  std::vector<std::size_t> spikes;
  for (std::size_t i = 0; i < n; ++i) {
    double v = std::sin(1e-4 * static_cast<double>(i));
    if (i % 99'991 == 7) v = (spikes.size() % 2 == 0 ? 10.0 : -10.0), spikes.push_back(i);
    const double t = 1e-3 * static_cast<double>(i);
    both.add(t, std::array<double, 2>{v, std::cos(3e-4 * static_cast<double>(i))});
    alone.add(t, -v);
  }
  std::vector<double> t, t_alone, v_alone;
  std::vector<std::vector<double>> v;
  both.take(t, v);
  alone.take(t_alone, v_alone);
  EXPECT_GE(t.size(), 2 * buckets);
  EXPECT_LE(t.size(), 4 * buckets);
  EXPECT_TRUE(std::is_sorted(t.begin(), t.end()));
  EXPECT_EQ(t, t_alone) << "the same times whatever the values: the buckets depend on the row count only";
  EXPECT_EQ(t.front(), 0.0);
  EXPECT_DOUBLE_EQ(t.back(), 1e-3 * static_cast<double>(n - 1));
  // Each spike on a row of its own bucket: at least `buckets` buckets, so at most n / buckets rows wide.
  const double width_s = 1e-3 * static_cast<double>(n) / buckets;
  for (std::size_t i : spikes) {
    const double ti = 1e-3 * static_cast<double>(i);
    bool found = false;
    for (std::size_t k = 0; k < t.size(); ++k) found |= std::abs(t[k] - ti) <= width_s && std::abs(v[0][k]) == 10.0;
    EXPECT_TRUE(found) << "spike at " << ti << " s lost";
  }
  EXPECT_DOUBLE_EQ(*std::max_element(v[0].begin(), v[0].end()), 10.0);
  EXPECT_DOUBLE_EQ(*std::min_element(v[0].begin(), v[0].end()), -10.0);
  EXPECT_DOUBLE_EQ(*std::max_element(v_alone.begin(), v_alone.end()), 10.0);
  EXPECT_DOUBLE_EQ(*std::max_element(v[1].begin(), v[1].end()), 1.0);
}

TEST(MinMaxDecimator, AGapBreaksItsColumnAtASharedRowAndOnlyThatColumn) {
  const std::size_t n = 10000, buckets = 50;
  for (const bool streamed : {true, false}) {
    auto d = streamed ? hil::MinMaxDecimator(buckets / 2, 2) : hil::MinMaxDecimator::for_length(n, buckets, 2);
    for (std::size_t i = 0; i < n; ++i) {
      const double x = static_cast<double>(i);
      const bool gap = i >= 5000 && i < 5003;
      d.add(x, std::array<double, 2>{gap ? kNan : std::sin(0.01 * x), std::cos(0.01 * x)});
    }
    std::vector<double> t;
    std::vector<std::vector<double>> v;
    d.take(t, v);
    const char* mode = streamed ? "streamed" : "for_length";
    ASSERT_EQ(v[0].size(), t.size());
    EXPECT_TRUE(std::is_sorted(t.begin(), t.end())) << mode;
    std::vector<std::size_t> gaps;
    for (std::size_t k = 0; k < t.size(); ++k)
      if (std::isnan(v[0][k])) gaps.push_back(k);
    ASSERT_FALSE(gaps.empty()) << mode << ": the gap is lost";
    // The break sits between the last row drawn before the gap and the first after it.
    EXPECT_GT(gaps.front(), 0u);
    EXPECT_LT(gaps.back() + 1, t.size());
    EXPECT_LE(t[gaps.front() - 1], 5000.0) << mode;
    EXPECT_GE(t[gaps.back() + 1], 5000.0) << mode;
    EXPECT_EQ(std::count_if(v[1].begin(), v[1].end(), [](double y) { return std::isnan(y); }), 0) << mode;
    EXPECT_EQ(t.front(), 0.0);
    EXPECT_EQ(t.back(), static_cast<double>(n - 1));
  }
}

TEST(MinMaxDecimator, ARunOfGapsIsOneRowNeverAtTheEnds) {
  auto d = hil::MinMaxDecimator::for_length(9, 100);
  const double inf = std::numeric_limits<double>::infinity();
  const double y[] = {kNan, 1.0, 2.0, kNan, inf, 3.0, 4.0, kNan, kNan};
  for (std::size_t i = 0; i < std::size(y); ++i) d.add(static_cast<double>(i), y[i]);
  std::vector<double> t, v;
  d.take(t, v);
  ASSERT_EQ(v.size(), 5u);
  EXPECT_EQ(t, (std::vector<double>{1, 2, 3, 5, 6}));
  EXPECT_EQ(v[0], 1);
  EXPECT_EQ(v[1], 2);
  EXPECT_TRUE(std::isnan(v[2]));
  EXPECT_EQ(v[3], 3);
  EXPECT_EQ(v[4], 4);
}

TEST(MinMaxDecimator, ARowWithoutATimeIsAGapInEveryColumn) {
  hil::MinMaxDecimator d(10, 2);
  d.add(0, std::array<double, 2>{1, 5});
  d.add(kNan, std::array<double, 2>{2, 6});
  d.add(2, std::array<double, 2>{3, 7});
  std::vector<double> t;
  std::vector<std::vector<double>> v;
  d.take(t, v);
  ASSERT_EQ(t.size(), 3u);
  EXPECT_EQ(t[0], 0);
  EXPECT_EQ(t[2], 2);
  EXPECT_TRUE(std::isnan(v[0][1]) && std::isnan(v[1][1]));
  EXPECT_EQ(v[0][2], 3);
  EXPECT_EQ(v[1][2], 7);
}

}  // namespace
