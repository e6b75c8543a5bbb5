// Test helper: loads a report.html in headless Debian Chromium and reads back what its script
// recorded (analysis/report's report.js sets data-plots / data-plot-errors on <body> and
// data-rendered / data-ink on each plot canvas). Used by the report, sim and workbench suites.
// Chromium missing is an error, not a skip: the test setup (scripts/setup.sh --test) installs it.
#pragma once

#include <chrono>
#include <filesystem>
#include <string>
#include <vector>

namespace hil::test {

struct CanvasInfo {
  bool rendered = false;  // data-rendered="1"
  bool empty = false;     // data-empty="1": the plot says "no data"
  long ink = -1;          // data-ink: pixels the data drew (-1: attribute missing)
};

struct BrowserResult {
  std::string error;                 // empty when Chromium ran and the page published its counters
  int plots = -1;                    // <body data-plots>: plots rendered
  int plot_errors = -1;              // <body data-plot-errors>: exceptions caught while rendering
  std::string first_error;           // <body data-plot-error-first>
  std::vector<CanvasInfo> canvases;  // each <canvas class="hil-plot">, in page order
  long min_ink = -1;                 // smallest ink over the canvases not marked empty (-1: none)
  std::string dom;                   // the DOM after the scripts ran, for further assertions

  // Ran, no errors, every canvas rendered, and every non-empty one drew something.
  bool ok() const;
  std::string summary() const;  // one line for test failure messages
  // An attribute of <body> as the page left it (e.g. one a test script set); empty if absent.
  std::string body_attribute(const std::string& name) const;
};

// $HIL_CHROMIUM if set, else the first of /usr/bin/chromium, chromium-browser, google-chrome
// found; empty if none.
std::filesystem::path find_chromium();

// Runs `chromium --headless ... --virtual-time-budget=10000 --dump-dom file://<html>` with a fresh
// profile and parses the DOM. Chromium and its children are killed if it overruns `timeout`.
BrowserResult check_report_in_chromium(const std::filesystem::path& html,
                                       std::chrono::seconds timeout = std::chrono::seconds(120));

// Saves a PNG of the page's first width x height pixels; returns an error text, empty on success.
std::string screenshot_in_chromium(const std::filesystem::path& html, const std::filesystem::path& png, int width = 1400,
                                   int height = 2000, std::chrono::seconds timeout = std::chrono::seconds(120));

}  // namespace hil::test
