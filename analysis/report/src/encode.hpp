// Internals of the report writer, visible to its tests: number formatting, decimation, escaping.
#pragma once

#include <cstddef>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace hil::report::detail {

// Writes `v` with 6 significant digits in the shortest form ("12.5", "0.000123", "1.5e-07") and
// returns the end. Needs 16 chars of room. Non-finite values are written as "null" (JSON gap).
char* format_number(char* out, double v);

// Decimated series: y NaN marks a gap (written as null). Points are in input order.
struct Decimated {
  std::vector<double> x, y;
};

enum class Thin { line, points };

// line: min/max decimation over max_buckets index buckets (hil::MinMaxDecimator::for_length: per
// bucket a row at its first and one at its last x holding the bucket's min and max y in input
// order, a gap row where a bucket holds a non-finite point, the first and last x always). Then
// drops interior rows of runs of equal y (the drawn line is the same), which shrinks steps and
// constants to their corners.
// points: if n > 2 * max_buckets, keeps the first point in each cell of a 256 x 256 grid over the
// data's bounding box (the scatter's shape survives, its density does not).
// Points with x <= 0 (x_log) or y <= 0 (y_log) are left out without a gap.
Decimated decimate(std::span<const double> x, std::span<const double> y, std::size_t max_buckets, Thin thin, bool x_log,
                   bool y_log);

// Line series that share their x, decimated together as `decimate` does one: over the same
// buckets, so they keep sharing their x (one row per x when a plot merges them into a table). A
// row is a run's interior (and dropped) only where every series is flat. Rows with x <= 0 (x_log)
// are left out; with y_log a single series leaves out its rows with y <= 0, several series draw
// their y <= 0 as gaps (a row is shared).
struct DecimatedShared {
  std::vector<double> x;
  std::vector<std::vector<double>> y;  // one per series, each as long as x
};
DecimatedShared decimate_shared(std::span<const double> x, std::span<const std::span<const double>> ys, std::size_t max_buckets,
                                bool x_log, bool y_log);

// Appends `v` as a JSON array of format_number values.
void append_numbers(std::string& out, std::span<const double> v);

// Text for HTML element content and attribute values: & < > " ' escaped.
std::string html_escape(std::string_view text);

// A JSON string literal that is also safe inside <script>: < > & are written as \u003c etc., and
// invalid UTF-8 is replaced rather than thrown on.
std::string json_string(std::string_view text);

}  // namespace hil::report::detail
