// Min/max decimation of rows (a time and one value per column) that arrive one at a time, in
// bounded memory whatever their number, for plots. The one decimator of the tree: the campaign
// report, compare/diagnose and the report writer all use it.
//
// Every column is cut into the SAME index buckets, and each bucket is written as the same two
// rows for every column (three with a gap, see below): one at the time of the bucket's first
// sample, one at the time of its last. A column's values on those rows are its smallest and its
// largest value in the bucket, in the order they came. So a plotted point means: "within the
// bucket that starts (or ends) here, the series reached this value"; every spike is drawn (its
// time moved by less than a bucket), and the columns share their times, so a plot that merges
// them into one table (dygraphs) gets one row per output row, not the union of each column's own
// times. A bucket of one sample is that sample: a short series is kept whole.
//
// A non-finite value (or time) is a gap: the line must break there. A bucket where any column has
// a gap gets a third row between the two (at the first gap's time, or midway when that is not
// strictly inside), and each column fills its rows with its extremes and one NaN marker in the
// order they came, repeating its last entry where it has fewer than the rows. Rows where every
// column is NaN are written once per run and never leading or trailing. A bucket where no sample
// has a finite time is one all-NaN row at the previous row's time.
//
// Two modes:
//   streamed (a simulated run, a replayed measurement: the length is not known in advance): when
//     there are 2 x max_buckets buckets, neighbours merge pairwise and each bucket covers twice as
//     many rows. The buckets depend only on the row count, so two decimators fed the same times
//     give the same output times wherever neither has a gap;
//   for_length (the report writer, which holds the whole series): bucket b covers rows
//     [b n / B, (b + 1) n / B) of the n announced, B = buckets, or every row its own bucket when
//     n <= 2 x buckets.
// Not for the real-time path: add() may allocate.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

namespace hil {

class MinMaxDecimator {
 public:
  explicit MinMaxDecimator(std::size_t max_buckets, std::size_t columns = 1);
  // Fixed index buckets over `samples` rows, at most `buckets` of them.
  static MinMaxDecimator for_length(std::size_t samples, std::size_t buckets, std::size_t columns = 1);

  std::size_t columns() const { return columns_; }
  // One row: `values` has columns() entries (extra ones are ignored, missing ones are gaps).
  void add(double t, std::span<const double> values);
  void add(double t, double value) { add(t, std::span<const double>(&value, 1)); }

  // The rows in input order: their times, and per column one value per row (NaN: a gap).
  // Streamed: between max_buckets and 2 x max_buckets buckets (a short series: every row).
  void take(std::vector<double>& t_out, std::vector<std::vector<double>>& values_out) const;
  // The first column only.
  void take(std::vector<double>& t_out, std::vector<double>& value_out) const;

 private:
  static constexpr std::size_t kNone = static_cast<std::size_t>(-1);
  struct Sample {
    std::size_t i = kNone;  // row index in the input; kNone: no such sample
    double v = 0;
  };
  struct Extremes {  // one column in one bucket
    Sample min, max;
    std::size_t gap = kNone;  // the first row where the column is not finite
  };
  struct Bucket {
    double t_first = 0, t_last = 0;  // finite times of the first and last rows that have one
    bool has_t = false;
    std::size_t gap = kNone;  // the first row where any column is not finite
    double t_gap = 0;
  };
  void open_bucket();
  void merge();
  std::size_t columns_, max_buckets_;
  std::vector<Bucket> buckets_;
  std::vector<Extremes> extremes_;          // columns_ per bucket
  std::size_t per_bucket_ = 1, count_ = 0;  // streamed: rows per bucket, rows in the last bucket
  std::size_t added_ = 0;                   // rows seen
  // for_length: the announced length (0: streamed), the bucket count, the next bucket's first row.
  std::size_t length_ = 0, fixed_buckets_ = 0, next_start_ = 0;
};

}  // namespace hil
