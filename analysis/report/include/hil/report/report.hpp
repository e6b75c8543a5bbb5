// Offline HTML report writer: one self-contained report.html (inline CSS, JS and data; no network)
// with interactive plots drawn by Debian's dygraphs (embedded at build time): box/wheel zoom, pan,
// hover read-out, legend toggles, and x-zoom linked across figures of the same group. Used by `hilbench sim` and `hilbench compare/diagnose`.
//
// Series are decimated when added (min and max per index bucket, at most kMaxBuckets buckets;
// hil/minmax_decimator.hpp), so a Document holds only what it will write and a million-point
// series costs a few milliseconds. Line and step series of a figure with the same x are decimated
// over the same buckets and written with one x, so the plot's table has a row per x, not the
// union of every series' own.
// Not real-time safe: allocates, formats and does file I/O.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace hil::report {

// In the head of every page Document::html() makes: an existing file without it is not a report
// the tool wrote, and is not replaced (hil/output_path.hpp).
inline constexpr std::string_view kGeneratorTag = "<meta name=\"generator\" content=\"hilbench report\">";

// A series longer than 2 * kMaxBuckets points is reduced to the min and max of each of
// kMaxBuckets index buckets, drawn at the bucket's first and last x; NaN gaps survive.
inline constexpr int kMaxBuckets = 4000;

struct Series {
  std::string name = "";                                        // legend text, with unit if it differs from the axis
  std::vector<double> x = {}, y = {};                           // same length; NaN in either breaks the line
  std::string color = "";                                       // any CSS colour; empty: the figure's palette in order
  enum class Style { line, step, points } style = Style::line;  // step: holds y until next x
  bool dashed = false;
  // Thinned data: the samples `x` and `y` stand for (0: x's size). A served report fetches the
  // samples of a zoomed window from `source_run`'s telemetry (GET /api/runs/RUN/telemetry, column
  // `source_column`); a plot says when it is thinned and what a zoom will show.
  std::size_t samples = 0;
  std::string source_run = "", source_column = "";
};

struct Band {  // shaded x-interval, e.g. a failing time window
  double x0 = 0, x1 = 0;
  std::string label = "";   // in the cursor's read-out over it
  std::string color = "";   // empty: translucent red
  std::string legend = "";  // its legend entry, one for every band of that name; empty: the label
};

struct Marker {  // a labelled vertical line at x, e.g. an event of the run (an injected gap change)
  double x = 0;
  std::string label = "";
  std::string color = "";  // empty: dark red
};

struct HLine {  // horizontal reference, e.g. a confidence bound or a tolerance
  double y = 0;
  std::string label = "";
  bool dashed = true;
};

struct Figure {
  std::string title = "", x_label = "", y_label = "";  // labels carry units: "time [s]", "pressure [MPa]"
  std::vector<Series> series = {};
  std::vector<Band> bands = {};
  std::vector<HLine> hlines = {};
  std::vector<Marker> markers = {};
  std::string group = "";             // figures with the same non-empty group share x zoom and cursor
  bool x_log = false, y_log = false;  // on a log axis, values <= 0 are left out
  int height_px = 260;
  int max_buckets = kMaxBuckets;  // lines and steps: min/max of at most this many buckets (>= 16)
};

struct Bars {  // grouped bar chart: one bar per (category, group)
  std::string title = "", y_label = "";
  std::vector<std::string> categories = {};
  std::vector<std::pair<std::string, std::vector<double>>> groups = {};  // name, one value per category
  int height_px = 260;
};

struct Heatmap {  // a value per (x, y) cell as a table of coloured cells, e.g. a metric over two sweep axes
  std::string title = "", x_label = "", y_label = "", value_label = "";
  std::vector<std::string> x_ticks = {}, y_ticks = {};
  std::vector<std::vector<double>> values = {};  // [y][x]; NaN: no value, a blank cell
  std::vector<std::vector<bool>> marked = {};    // [y][x]: outlined and flagged "x" (failing); empty: none
  int digits = 3;                                // significant digits of the value shown in each cell
  // The pass band of the value (a threshold: either bound or both). With one, a cell is green when
  // its value is inside, red when outside (or missing), darker the further from the nearest bound.
  std::optional<double> pass_min = std::nullopt, pass_max = std::nullopt;
  // [y][x]: a second, smaller line in the cell under its value (e.g. "2 of 3 fail"); empty: none.
  std::vector<std::vector<std::string>> notes = {};
};

class Document {
 public:
  explicit Document(std::string title);

  void heading(std::string text, int level = 2);  // level 1..4
  void paragraph(std::string text);               // plain text, HTML-escaped
  // A paragraph of `text` then a link to `href` (a relative path or URL, shown as `link_text`).
  void link(std::string text, std::string href, std::string link_text);
  void note(std::string text, bool warning);  // highlighted box, e.g. "no candidate explains..."
  // Cells that look like numbers are right-aligned; clicking a header sorts by that column.
  void table(std::vector<std::string> header, std::vector<std::vector<std::string>> rows);
  // Throws std::invalid_argument if a series has x and y of different lengths.
  void figure(const Figure& fig);
  // Throws std::invalid_argument if a group does not have one value per category.
  void bars(const Bars& chart);
  // A table of cells, the value printed in each; works without JavaScript. Coloured by pass/fail:
  // against the pass band if the map has one, else red for marked cells and green for the others;
  // without either, from green (the smallest value) to red (the largest). A line under the map
  // says which. A cell coloured by pass/fail has the class hil-pass or hil-fail. Throws
  // std::invalid_argument if values, marked or notes (when given) is not y_ticks x x_ticks.
  void heatmap(const Heatmap& map);
  // Side-by-side layout: the blocks added until columns_end() fill n columns row by row (so add
  // run 1's pressure, run 2's pressure, ..., then run 1's angle, ...). No nesting.
  void columns_begin(int n);
  void columns_end();

  // The whole page as a string (what write() puts in the file).
  std::string html() const;
  // Atomic (hil::replace_file): a reader sees the old file or the whole new page. On failure the
  // temporary is removed, an existing `file` is untouched, and std::system_error names it.
  void write(const std::filesystem::path& file) const;

 private:
  void block(const std::string& html);  // appends one top-level block (a grid cell in columns)
  void open_block();
  void close_block();
  std::string page_head() const;  // html() is page_head() + body_ + page_tail()
  std::string page_tail() const;

  std::string title_;
  std::string body_;  // HTML of the blocks so far; figure data already decimated and encoded
  int next_id_ = 0;
  int plots_ = 0;    // figures and bar charts: the page carries dygraphs and the plot help only if > 0
  int columns_ = 0;  // > 0 while inside columns_begin/columns_end
};

}  // namespace hil::report
