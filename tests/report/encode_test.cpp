// The report writer's internals: number formatting, decimation, escaping.
#include "encode.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <random>
#include <set>
#include <span>
#include <utility>

#include <nlohmann/json.hpp>

using namespace hil::report::detail;

namespace {

std::string fmt(double v) {
  char buf[32];
  return std::string(buf, format_number(buf, v));
}

// Is y drawn at an x in [x0, x1]?
bool contains(const std::vector<double>& xs, const std::vector<double>& ys, double x0, double x1, double y) {
  for (std::size_t i = 0; i < xs.size(); ++i) {
    if (xs[i] >= x0 && xs[i] <= x1 && ys[i] == y) return true;
  }
  return false;
}

}  // namespace

TEST(FormatNumber, ShortestFormsAndSpecialValues) {
  EXPECT_EQ(fmt(0.0), "0");
  EXPECT_EQ(fmt(-0.0), "0");
  EXPECT_EQ(fmt(1.0), "1");
  EXPECT_EQ(fmt(12.5), "12.5");
  EXPECT_EQ(fmt(-3.25), "-3.25");
  EXPECT_EQ(fmt(0.1), "0.1");
  EXPECT_EQ(fmt(0.000123), "0.000123");
  EXPECT_EQ(fmt(17.9995), "17.9995");
  EXPECT_EQ(fmt(1234567.0), "1234570");
  EXPECT_EQ(fmt(3.14159265), "3.14159");
  EXPECT_EQ(fmt(9.999996), "10");
  EXPECT_EQ(fmt(0.09999996), "0.1");
  EXPECT_EQ(fmt(999999.6), "1000000");
  EXPECT_EQ(fmt(1e-7), "1e-07");
  EXPECT_EQ(fmt(2.5e12), "2.5e+12");
  EXPECT_EQ(fmt(NAN), "null");
  EXPECT_EQ(fmt(INFINITY), "null");
  EXPECT_EQ(fmt(-INFINITY), "null");
}

TEST(FormatNumber, RoundTripsToSixSignificantDigits) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> mantissa(1.0, 10.0);
  std::uniform_int_distribution<int> exponent(-12, 14);
  for (int i = 0; i < 200000; ++i) {
    const double v = (i % 2 ? -1 : 1) * mantissa(rng) * std::pow(10.0, exponent(rng));
    const std::string s = fmt(v);
    ASSERT_LE(s.size(), 16u) << s;
    char* end = nullptr;
    const double back = std::strtod(s.c_str(), &end);
    ASSERT_EQ(*end, '\0') << s;
    // 6 significant digits: the error is at most half a unit in the 6th digit.
    ASSERT_LE(std::abs(back - v), 5.000001e-6 * std::abs(v)) << v << " -> " << s;
    // Valid JSON number, no trailing zeros after a decimal point.
    ASSERT_TRUE(nlohmann::json::accept(s)) << s;
    if (s.find('.') != std::string::npos && s.find('e') == std::string::npos) {
      ASSERT_NE(s.back(), '0') << s;
    }
  }
}

TEST(FormatNumber, AppendNumbersWritesAJsonArray) {
  std::string out = "x=";
  const std::vector<double> v = {1.5, NAN, -2e-9, 100};
  append_numbers(out, v);
  EXPECT_EQ(out, "x=[1.5,null,-2e-09,100]");
  out.clear();
  append_numbers(out, std::vector<double>{});
  EXPECT_EQ(out, "[]");
}

TEST(Decimate, KeepsMinAndMaxOfEveryBucketAndTheEnds) {
  const std::size_t n = 100003, buckets = 100;
  std::vector<double> x(n), y(n);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0, 1);
  for (std::size_t i = 0; i < n; ++i) {
    x[i] = 0.001 * static_cast<double>(i);
    y[i] = std::sin(0.0007 * static_cast<double>(i)) + 0.1 * noise(rng) + (i % 7919 == 0 ? 5.0 : 0.0);
  }
  const auto d = decimate(x, y, buckets, Thin::line, false, false);
  ASSERT_FALSE(d.x.empty());
  EXPECT_LE(d.x.size(), 2 * buckets);
  EXPECT_EQ(d.x.front(), x.front()) << "the line spans the whole range";
  EXPECT_EQ(d.x.back(), x.back());
  EXPECT_TRUE(std::is_sorted(d.x.begin(), d.x.end())) << "points stay in input order";
  // Each bucket's extremes, drawn within the bucket (at its first or last x).
  for (std::size_t b = 0; b < buckets; ++b) {
    const std::size_t lo = b * n / buckets, hi = (b + 1) * n / buckets;
    const auto [mn, mx] = std::minmax_element(y.begin() + static_cast<long>(lo), y.begin() + static_cast<long>(hi));
    EXPECT_TRUE(contains(d.x, d.y, x[lo], x[hi - 1], *mn)) << "bucket " << b << " min";
    EXPECT_TRUE(contains(d.x, d.y, x[lo], x[hi - 1], *mx)) << "bucket " << b << " max";
  }
  for (std::size_t i = 0; i < n; i += 7919) {
    const std::size_t b = i * buckets / n;
    EXPECT_TRUE(contains(d.x, d.y, x[b * n / buckets], x[(b + 1) * n / buckets - 1], y[i])) << "spike at " << i;
  }
}

TEST(DecimateShared, SeriesOfOneXKeepOneXAndEachBucketsExtremes) {
  const std::size_t n = 50021, buckets = 64;
  std::vector<double> x(n);
  std::vector<std::vector<double>> y(3, std::vector<double>(n));
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0, 1);
  for (std::size_t i = 0; i < n; ++i) {
    const double k = static_cast<double>(i);
    x[i] = 0.001 * k;
    y[0][i] = std::floor(k / 7000);                                    // a step reference
    y[1][i] = y[0][i] + 0.2 * noise(rng) + (i % 4999 == 3 ? 4 : 0);    // its measurement, with spikes
    y[2][i] = (i >= 20000 && i < 20500) ? NAN : std::cos(0.0003 * k);  // a gap
  }
  const std::vector<std::span<const double>> ys = {y[0], y[1], y[2]};
  const auto d = decimate_shared(x, ys, buckets, false, false);
  ASSERT_EQ(d.y.size(), 3u);
  for (const auto& col : d.y) ASSERT_EQ(col.size(), d.x.size()) << "every series has a value (or a gap) at every shared x";
  EXPECT_LE(d.x.size(), 3 * buckets);
  EXPECT_EQ(d.x.front(), x.front());
  EXPECT_EQ(d.x.back(), x.back());
  EXPECT_TRUE(std::is_sorted(d.x.begin(), d.x.end()));
  for (std::size_t b = 0; b < buckets; ++b) {
    const std::size_t lo = b * n / buckets, hi = (b + 1) * n / buckets;
    for (std::size_t c = 0; c < 3; ++c) {
      double mn = INFINITY, mx = -INFINITY;
      for (std::size_t i = lo; i < hi; ++i) {
        if (std::isfinite(y[c][i])) mn = std::min(mn, y[c][i]), mx = std::max(mx, y[c][i]);
      }
      if (!std::isfinite(mn)) continue;
      EXPECT_TRUE(contains(d.x, d.y[c], x[lo], x[hi - 1], mn)) << "bucket " << b << " series " << c << " min";
      EXPECT_TRUE(contains(d.x, d.y[c], x[lo], x[hi - 1], mx)) << "bucket " << b << " series " << c << " max";
    }
  }
  // The gap breaks series 2 between its last point before and its first after; the others go on.
  std::vector<std::size_t> gaps;
  for (std::size_t k = 0; k < d.x.size(); ++k)
    if (std::isnan(d.y[2][k])) gaps.push_back(k);
  ASSERT_FALSE(gaps.empty());
  EXPECT_LE(d.x[gaps.front() - 1], x[20000]);
  EXPECT_GE(d.x[gaps.back() + 1], x[20499]);
  for (std::size_t c = 0; c < 2; ++c)
    EXPECT_EQ(std::count_if(d.y[c].begin(), d.y[c].end(), [](double v) { return std::isnan(v); }), 0);
}

TEST(DecimateShared, ShortSeriesAreKeptWholeButRowsFlatInEverySeries) {
  const std::vector<double> x = {0, 1, 2, 3, 4, 5, 6};
  const std::vector<double> a = {1, 1, 1, 1, 2, 2, 2}, b = {5, 5, 6, 5, 5, 5, 5};
  const std::vector<std::span<const double>> ys = {a, b};
  const auto d = decimate_shared(x, ys, 100, false, false);
  EXPECT_EQ(d.x, (std::vector<double>{0, 1, 2, 3, 4, 6}));  // 5 is flat in both
  EXPECT_EQ(d.y[0], (std::vector<double>{1, 1, 1, 1, 2, 2}));
  EXPECT_EQ(d.y[1], (std::vector<double>{5, 5, 6, 5, 5, 5}));
}

TEST(Decimate, ShortSeriesKeepAllButRedundantPointsOfFlatRuns) {
  const std::vector<double> x = {0, 1, 2, 3, 4, 5, 6};
  const std::vector<double> y = {1, 1, 1, 1, 2, 2, 3};
  const auto d = decimate(x, y, 100, Thin::line, false, false);
  EXPECT_EQ(d.x, (std::vector<double>{0, 3, 4, 5, 6}));
  EXPECT_EQ(d.y, (std::vector<double>{1, 1, 2, 2, 3}));
}

TEST(Decimate, FlatRunsWithXGoingBackAreKept) {
  const std::vector<double> x = {0, 5, 2, 3};
  const std::vector<double> y = {1, 1, 1, 1};
  const auto d = decimate(x, y, 100, Thin::line, false, false);
  EXPECT_EQ(d.x, (std::vector<double>{0, 5, 2, 3}));  // the excursion to 5 is visible
}

TEST(Decimate, NanGapsSurviveAsOneMarker) {
  const std::vector<double> x = {0, 1, 2, 3, 4, 5, 6, 7};
  const std::vector<double> y = {NAN, 1, 2, NAN, NAN, 3, 4, NAN};
  const auto d = decimate(x, y, 100, Thin::line, false, false);
  ASSERT_EQ(d.y.size(), 5u);  // no leading or trailing gap, one marker for the double NaN
  EXPECT_EQ(d.y[0], 1);
  EXPECT_EQ(d.y[1], 2);
  EXPECT_TRUE(std::isnan(d.y[2]));
  EXPECT_EQ(d.y[3], 3);
  EXPECT_EQ(d.y[4], 4);

  // Decimated too: a bucket holding a NaN keeps a gap marker between its neighbours.
  std::vector<double> bx(10000), by(10000);
  for (std::size_t i = 0; i < bx.size(); ++i) bx[i] = static_cast<double>(i), by[i] = std::sin(i * 0.01);
  by[5000] = NAN;
  const auto e = decimate(bx, by, 50, Thin::line, false, false);
  EXPECT_EQ(std::count_if(e.y.begin(), e.y.end(), [](double v) { return std::isnan(v); }), 1);
}

TEST(Decimate, LogAxesDropNonPositiveValuesWithoutAGap) {
  const std::vector<double> f = {0, 1, 2, 4, 8};
  const std::vector<double> p = {5, 1e-3, -1, 1e-5, 1e-6};
  const auto d = decimate(f, p, 100, Thin::line, true, true);
  EXPECT_EQ(d.x, (std::vector<double>{1, 4, 8}));
  EXPECT_EQ(std::count_if(d.y.begin(), d.y.end(), [](double v) { return std::isnan(v); }), 0);
}

TEST(Decimate, ScatterIsThinnedOnAGrid) {
  std::mt19937 rng(5);
  std::normal_distribution<double> g(0, 1);
  std::vector<double> x(1000000), y(1000000);
  std::set<std::pair<double, double>> input;
  for (std::size_t i = 0; i < x.size(); ++i) {
    x[i] = g(rng), y[i] = 0.5 * x[i] + 0.2 * g(rng);
    input.insert({x[i], y[i]});
  }
  const auto d = decimate(x, y, 4000, Thin::points, false, false);
  EXPECT_GT(d.x.size(), 1000u);
  EXPECT_LE(d.x.size(), 256u * 256u);
  for (std::size_t i = 0; i < d.x.size(); ++i) ASSERT_TRUE(input.count({d.x[i], d.y[i]}));
  // Small scatters are kept whole.
  const auto small = decimate(std::span(x).first(500), std::span(y).first(500), 4000, Thin::points, false, false);
  EXPECT_EQ(small.x.size(), 500u);
}

TEST(Escape, HtmlEscapesMarkup) {
  EXPECT_EQ(html_escape("<b>a & \"b\" 'c'</b>"), "&lt;b&gt;a &amp; &quot;b&quot; &#39;c&#39;&lt;/b&gt;");
}

TEST(Escape, JsonStringCannotCloseAScript) {
  const std::string hostile = "</script><script>alert(1)</script><!-- \"q\" \\ \n";
  const std::string s = json_string(hostile);
  EXPECT_EQ(s.find('<'), std::string::npos);
  EXPECT_EQ(s.find('>'), std::string::npos);
  EXPECT_EQ(nlohmann::json::parse(s).get<std::string>(), hostile);
}

TEST(Escape, InvalidUtf8IsReplacedNotThrown) {
  std::string s;
  ASSERT_NO_THROW(s = json_string("bad \xff\xfe byte"));
  EXPECT_TRUE(nlohmann::json::accept(s));
}
