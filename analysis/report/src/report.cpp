#include "hil/report/report.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>
#include <span>
#include <stdexcept>

#include "assets.hpp"
#include "encode.hpp"
#include "hil/line_file.hpp"

namespace hil::report {
namespace {

using detail::html_escape;
using detail::json_string;

const char* style_name(Series::Style s) {
  switch (s) {
    case Series::Style::step: return "step";
    case Series::Style::points: return "points";
    default: return "line";
  }
}

void append_number(std::string& out, double v) {
  char buf[32];
  out.append(buf, detail::format_number(buf, v));
}

// "a-b" style keys keep the embedded JSON small; report.js reads the same names. A series whose x
// is another's (x_of) writes "xOf" (that series' index) instead of its x.
void append_series(std::string& out, const Series& s, std::size_t index, std::size_t x_of, std::span<const double> x,
                   std::span<const double> y) {
  out += "{\"name\":" + json_string(s.name) + ",\"color\":" + json_string(s.color) + ",\"style\":\"" + style_name(s.style) +
         "\",\"dashed\":" + (s.dashed ? "true" : "false") + ",\"n\":" + std::to_string(std::max(s.samples, s.x.size()));
  if (!s.source_run.empty() && !s.source_column.empty())
    out += ",\"src\":{\"run\":" + json_string(s.source_run) + ",\"col\":" + json_string(s.source_column) + "}";
  if (x_of == index) {
    out += ",\"x\":";
    detail::append_numbers(out, x);
  } else {
    out += ",\"xOf\":" + std::to_string(x_of);
  }
  out += ",\"y\":";
  detail::append_numbers(out, y);
  out += '}';
}

// The figure's series, decimated: lines and steps with the same x together (they keep sharing it,
// so a plot merging them into one table gets no more rows than one of them), scatters alone.
void append_figure_series(std::string& out, const Figure& fig) {
  const std::size_t n = fig.series.size();
  std::vector<std::size_t> x_of(n);  // the first series with the same x, for lines and steps
  for (std::size_t i = 0; i < n; ++i) {
    x_of[i] = i;
    if (fig.series[i].style == Series::Style::points) continue;
    for (std::size_t j = 0; j < i; ++j) {
      if (x_of[j] == j && fig.series[j].style != Series::Style::points && fig.series[j].x == fig.series[i].x) {
        x_of[i] = j;
        break;
      }
    }
  }
  std::vector<detail::DecimatedShared> groups(n);  // at each group's first series
  std::vector<std::size_t> column(n, 0);           // the series' column in its group
  for (std::size_t i = 0; i < n; ++i) {
    if (x_of[i] != i || fig.series[i].style == Series::Style::points) continue;
    std::vector<std::span<const double>> ys;
    for (std::size_t j = i; j < n; ++j) {
      if (x_of[j] == i) column[j] = ys.size(), ys.push_back(fig.series[j].y);
    }
    groups[i] = detail::decimate_shared(fig.series[i].x, ys, static_cast<std::size_t>(std::max(fig.max_buckets, 16)), fig.x_log,
                                        fig.y_log);
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (i > 0) out += ',';
    const Series& s = fig.series[i];
    if (s.style == Series::Style::points) {
      const auto d = detail::decimate(s.x, s.y, kMaxBuckets, detail::Thin::points, fig.x_log, fig.y_log);
      append_series(out, s, i, i, d.x, d.y);
    } else {
      const auto& g = groups[x_of[i]];
      append_series(out, s, i, x_of[i], g.x, g.y[column[i]]);
    }
  }
}

// Figure data sits in a non-executed <script> next to its canvas; report.js parses it.
constexpr std::string_view kDataOpen = "<script type=\"application/json\" class=\"hil-data\">";
constexpr std::string_view kDataClose = "</script></figure>";

std::string figure_head(const std::string& kind, int id, const std::string& title) {
  return "<figure class=\"hil-fig hil-" + kind + "\" id=\"fig" + std::to_string(id) + "\"><figcaption>" + html_escape(title) +
         "</figcaption>";
}

bool looks_numeric(const std::string& cell) {
  if (cell.empty()) return false;
  double v = 0;
  const char* b = cell.data() + (cell[0] == '+' ? 1 : 0);
  const char* e = cell.data() + cell.size();
  const auto r = std::from_chars(b, e, v);
  // Allow a trailing unit or percent sign ("12.5 %", "3 ms") so metric tables align too.
  return r.ec == std::errc() && (r.ptr == e || *r.ptr == ' ' || *r.ptr == '%');
}

}  // namespace

Document::Document(std::string title) : title_(std::move(title)) {}

void Document::open_block() {
  if (columns_ > 0) body_ += "<div class=\"hil-cell\">";
}

void Document::close_block() { body_ += columns_ > 0 ? "</div>\n" : "\n"; }

void Document::block(const std::string& html) {
  open_block();
  body_ += html;
  close_block();
}

void Document::heading(std::string text, int level) {
  const char digit = static_cast<char>('0' + std::clamp(level, 1, 4));
  std::string html = "<h0>";
  html[2] = digit;
  html += html_escape(text);
  html += "</h0>";
  html[html.size() - 2] = digit;
  block(html);
}

void Document::paragraph(std::string text) { block("<p>" + html_escape(text) + "</p>"); }

void Document::link(std::string text, std::string href, std::string link_text) {
  // Relative paths and http(s) only: a page opened from disk should not run a javascript: link.
  const auto colon = href.find(':'), slash = href.find('/');
  const bool scheme = colon != std::string::npos && (slash == std::string::npos || colon < slash);
  const bool safe = !scheme || href.rfind("http://", 0) == 0 || href.rfind("https://", 0) == 0;
  block("<p>" + html_escape(text) +
        (safe ? "<a href=\"" + html_escape(href) + "\">" + html_escape(link_text) + "</a>" : html_escape(link_text)) + "</p>");
}

void Document::note(std::string text, bool warning) {
  block(std::string("<div class=\"hil-note") + (warning ? " hil-warn" : "") + "\" role=\"note\">" + html_escape(text) + "</div>");
}

void Document::table(std::vector<std::string> header, std::vector<std::vector<std::string>> rows) {
  std::string h = "<div class=\"hil-table-wrap\"><table class=\"hil-table\"><thead><tr>";
  for (const auto& c : header) h += "<th>" + html_escape(c) + "</th>";
  h += "</tr></thead><tbody>";
  for (const auto& row : rows) {
    h += "<tr>";
    for (const auto& c : row) {
      h += looks_numeric(c) ? "<td class=\"num\">" : "<td>";
      h += html_escape(c) + "</td>";
    }
    h += "</tr>";
  }
  h += "</tbody></table></div>";
  block(h);
}

void Document::heatmap(const Heatmap& map) {
  const auto fits = [&](const auto& grid) {
    if (grid.size() != map.y_ticks.size()) return false;
    for (const auto& row : grid)
      if (row.size() != map.x_ticks.size()) return false;
    return true;
  };
  if (!fits(map.values) || (!map.marked.empty() && !fits(map.marked)) || (!map.notes.empty() && !fits(map.notes))) {
    throw std::invalid_argument("report heatmap '" + map.title + "': needs " + std::to_string(map.y_ticks.size()) + " rows of " +
                                std::to_string(map.x_ticks.size()) + " cells");
  }
  const bool banded = map.pass_min.has_value() || map.pass_max.has_value();
  const bool by_mark = !banded && !map.marked.empty();
  // Signed distance of a value from the pass band's nearest bound: > 0 inside, < 0 outside.
  const auto inside = [&](double v) {
    double d = std::numeric_limits<double>::infinity();
    if (map.pass_min) d = std::min(d, v - *map.pass_min);
    if (map.pass_max) d = std::min(d, *map.pass_max - v);
    return d;
  };
  // Scales for the shades: the value range, or the furthest cell on each side of the band.
  double lo = std::numeric_limits<double>::infinity(), hi = -lo, in_max = 0, out_max = 0;
  for (const auto& row : map.values) {
    for (double v : row) {
      if (!std::isfinite(v)) continue;
      lo = std::min(lo, v);
      hi = std::max(hi, v);
      if (!banded) continue;
      const double d = inside(v);
      double& furthest = d >= 0 ? in_max : out_max;
      if (std::isfinite(d)) furthest = std::max(furthest, std::abs(d));
    }
  }
  std::string h = "<div class=\"hil-table-wrap\"><table class=\"hil-table\"><caption style=\"text-align:left\"><b>" +
                  html_escape(map.title) + "</b> " + html_escape(map.value_label) + "</caption><thead><tr><th>" +
                  html_escape(map.y_label) + " \\ " + html_escape(map.x_label) + "</th>";
  for (const auto& x : map.x_ticks) h += "<th>" + html_escape(x) + "</th>";
  h += "</tr></thead><tbody>";
  char text[64];
  for (std::size_t y = 0; y < map.y_ticks.size(); ++y) {
    h += "<tr><th>" + html_escape(map.y_ticks[y]) + "</th>";
    for (std::size_t x = 0; x < map.x_ticks.size(); ++x) {
      const double v = map.values[y][x];
      const bool marked = !map.marked.empty() && map.marked[y][x];
      std::string style;
      const char* verdict = "";  // the cell's colour as a class, for readers of the page
      if (banded) {
        // Green inside the band, red outside; lighter at the bound, darker away from it.
        const double d = std::isfinite(v) ? inside(v) : -std::numeric_limits<double>::infinity();
        const bool pass = d >= 0;
        const double scale = pass ? in_max : out_max;
        const double f = !std::isfinite(d) ? 1.0 : scale > 0 ? std::abs(d) / scale : 0.0;
        std::snprintf(text, sizeof text, "background:hsl(%d,60%%,%.0f%%);", pass ? 120 : 0, 86.0 - 22.0 * f);
        style = text;
        verdict = pass ? " hil-pass" : " hil-fail";
      } else if (by_mark) {
        style = marked ? "background:hsl(0,60%,76%);" : "background:hsl(120,60%,76%);";
        verdict = marked ? " hil-fail" : " hil-pass";
      } else if (std::isfinite(v)) {
        // Green (hue 120) for the smallest value to red (hue 0) for the largest, light enough for black text.
        const double f = hi > lo ? (v - lo) / (hi - lo) : 0.0;
        std::snprintf(text, sizeof text, "background:hsl(%.0f,70%%,72%%);", 120.0 * (1.0 - f));
        style = text;
      }
      if (std::isfinite(v)) {
        std::snprintf(text, sizeof text, "%.*g", map.digits, v);
      } else {
        std::snprintf(text, sizeof text, "-");
      }
      if (marked) style += "outline:2px solid #b00;outline-offset:-2px;font-weight:bold;";
      h += std::string("<td class=\"num") + verdict + "\" style=\"" + style + "\">" + html_escape(text) +
           (marked ? " &#x2717;" : "");
      if (!map.notes.empty() && !map.notes[y][x].empty())
        h += "<br><small class=\"hil-cell-note\">" + html_escape(map.notes[y][x]) + "</small>";
      h += "</td>";
    }
    h += "</tr>";
  }
  h += "</tbody></table><p class=\"hil-map-key\">";
  if (banded) {
    const auto bound = [&](const char* relation, double v) {
      char num[32];
      std::snprintf(num, sizeof num, "%.*g", map.digits, v);
      return std::string(relation) + num;
    };
    std::string band = map.pass_min ? bound("&ge; ", *map.pass_min) : "";
    if (map.pass_max) band += (map.pass_min ? " and " : "") + bound("&le; ", *map.pass_max);
    h += "Colour: green passes (" + band + "), red fails; darker is further from the threshold.";
  } else if (by_mark) {
    h += "Colour: red where a point of the cell fails, green where all pass.";
  } else {
    h += "Colour: green for the smallest value to red for the largest.";
  }
  h += "</p></div>";
  block(h);
}

void Document::figure(const Figure& fig) {
  for (const auto& s : fig.series) {
    if (s.x.size() != s.y.size()) {
      throw std::invalid_argument("report figure '" + fig.title + "': series '" + s.name + "' has " + std::to_string(s.x.size()) +
                                  " x but " + std::to_string(s.y.size()) + " y values");
    }
  }
  // Encoded straight into body_: the data is the bulk of the page, copies of it cost time.
  const std::size_t mark = body_.size();
  try {
    open_block();
    std::string& json = body_;
    json += figure_head("plot", next_id_++, fig.title);
    json += kDataOpen;
    json += "{\"kind\":\"plot\",\"xLabel\":" + json_string(fig.x_label) + ",\"yLabel\":" + json_string(fig.y_label) +
            ",\"group\":" + json_string(fig.group) + ",\"xLog\":" + (fig.x_log ? "true" : "false") +
            ",\"yLog\":" + (fig.y_log ? "true" : "false") + ",\"height\":" + std::to_string(std::max(fig.height_px, 80)) +
            ",\"series\":[";
    append_figure_series(json, fig);
    json += "],\"bands\":[";
    for (std::size_t i = 0; i < fig.bands.size(); ++i) {
      const auto& b = fig.bands[i];
      json += i > 0 ? ",{\"x0\":" : "{\"x0\":";
      append_number(json, b.x0);
      json += ",\"x1\":";
      append_number(json, b.x1);
      json += ",\"label\":" + json_string(b.label) + ",\"legend\":" + json_string(b.legend) +
              ",\"color\":" + json_string(b.color) + "}";
    }
    json += "],\"hlines\":[";
    for (std::size_t i = 0; i < fig.hlines.size(); ++i) {
      const auto& l = fig.hlines[i];
      json += i > 0 ? ",{\"y\":" : "{\"y\":";
      append_number(json, l.y);
      json += ",\"label\":" + json_string(l.label) + ",\"dashed\":" + (l.dashed ? "true" : "false") + "}";
    }
    json += "],\"markers\":[";
    for (std::size_t i = 0; i < fig.markers.size(); ++i) {
      const auto& m = fig.markers[i];
      json += i > 0 ? ",{\"x\":" : "{\"x\":";
      append_number(json, m.x);
      json += ",\"label\":" + json_string(m.label) + ",\"color\":" + json_string(m.color) + "}";
    }
    json += "]}";
    json += kDataClose;
    close_block();
    ++plots_;
  } catch (...) {
    body_.resize(mark);  // no half figure in the page
    throw;
  }
}

void Document::bars(const Bars& chart) {
  for (const auto& [name, values] : chart.groups) {
    if (values.size() != chart.categories.size()) {
      throw std::invalid_argument("report bars '" + chart.title + "': group '" + name + "' has " + std::to_string(values.size()) +
                                  " values for " + std::to_string(chart.categories.size()) + " categories");
    }
  }
  std::string json = "{\"kind\":\"bars\",\"yLabel\":" + json_string(chart.y_label) +
                     ",\"height\":" + std::to_string(std::max(chart.height_px, 80)) + ",\"categories\":[";
  for (std::size_t i = 0; i < chart.categories.size(); ++i) {
    if (i > 0) json += ',';
    json += json_string(chart.categories[i]);
  }
  json += "],\"groups\":[";
  for (std::size_t i = 0; i < chart.groups.size(); ++i) {
    if (i > 0) json += ',';
    json += "{\"name\":" + json_string(chart.groups[i].first) + ",\"values\":";
    detail::append_numbers(json, chart.groups[i].second);
    json += '}';
  }
  json += "]}";
  block(figure_head("bars", next_id_++, chart.title) + std::string(kDataOpen) + json + std::string(kDataClose));
  ++plots_;
}

void Document::columns_begin(int n) {
  if (columns_ > 0) throw std::logic_error("report: columns_begin inside columns (no nesting)");
  columns_ = std::clamp(n, 1, 6);
  body_ += "<div class=\"hil-cols\" style=\"grid-template-columns:repeat(" + std::to_string(columns_) + ",minmax(0,1fr))\">\n";
}

void Document::columns_end() {
  if (columns_ == 0) throw std::logic_error("report: columns_end without columns_begin");
  columns_ = 0;
  body_ += "</div>\n";
}

std::string Document::page_head() const {
  std::string head;
  head.reserve(detail::kDygraphCss.size() + detail::kReportCss.size() + 1024);
  head +=
      "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n"
      "<meta name=\"viewport\" content=\"width=device-width,initial-scale=1\">\n";
  head += kGeneratorTag;
  head += "\n<title>";
  head += html_escape(title_);
  head += "</title>\n<style>\n";
  head += detail::kDygraphCss;
  head += "\n";
  head += detail::kReportCss;
  head += "</style>\n</head>\n<body>\n<header class=\"hil-header\"><h1>";
  head += html_escape(title_);
  head += "</h1>";
  // How to use the plots, only where there are plots (a sweep report has tables only).
  if (plots_ > 0) {
    head +=
        "<p class=\"hil-help\">Plots: drag to zoom in x &middot; shift+drag to pan &middot; "
        "click a plot then wheel (or ctrl+wheel) to zoom &middot; double-click to reset &middot; hover for values &middot; "
        "click a legend entry to hide it, double-click to show it alone.</p>";
  }
  head += "</header>\n<main>\n";
  return head;
}

std::string Document::page_tail() const {
  std::string tail;
  tail.reserve(detail::kDygraphJs.size() + detail::kReportJs.size() + 256);
  if (columns_ > 0) tail += "</div>\n";  // an unclosed columns_begin still gives valid HTML
  tail += "</main>\n";
  // The plotting library only where there is something to plot; report.js also sorts tables.
  if (plots_ > 0) {
    tail += "<script>\n";
    tail += detail::kDygraphJs;
    tail += "\n</script>\n";
  }
  tail += "<script>\n";
  tail += detail::kReportJs;
  tail += "</script>\n</body></html>\n";
  return tail;
}

std::string Document::html() const { return page_head() + body_ + page_tail(); }

void Document::write(const std::filesystem::path& file) const {
  const std::string head = page_head(), tail = page_tail();
  const std::string_view parts[] = {head, body_, tail};  // the body is not copied into one page
  hil::replace_file(file, parts);
}

}  // namespace hil::report
