// A sweep run in a test as a user runs it (plan, points, outputs) and its sweep.csv read back as
// rows of cells: the campaign tests' one way to do it (tracking_corner_test, compensator_part_test).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "hil/bench/campaign/sweep.hpp"
#include "temp_file.hpp"

namespace hil::test {

// CSV text as rows of cells (comment lines and empty lines skipped; no quoting in these files).
inline std::vector<std::vector<std::string>> csv_rows(const std::string& text) {
  std::vector<std::vector<std::string>> rows;
  std::stringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::vector<std::string> cells;
    std::stringstream l(line);
    for (std::string c; std::getline(l, c, ',');) cells.push_back(c);
    rows.push_back(cells);
  }
  return rows;
}

// Where `name` is in the header (a failure naming it when it is not).
inline std::size_t column(const std::vector<std::string>& header, const std::string& name) {
  const auto it = std::find(header.begin(), header.end(), name);
  EXPECT_NE(it, header.end()) << name;
  return static_cast<std::size_t>(it - header.begin());
}

// Runs the sweep file `sweep` (expecting `points` points) into dir/out and returns its sweep.csv's
// rows, the header first; empty (with a failure) when the plan or the outputs are not as expected.
inline std::vector<std::vector<std::string>> run_sweep_rows(const TempDir& dir, const std::filesystem::path& sweep,
                                                            std::size_t points) {
  using namespace hil::bench;
  const SweepPlan plan = plan_sweep(sweep);
  EXPECT_EQ(plan.points.size(), points);
  if (plan.points.size() != points) return {};
  const std::filesystem::path out = dir.path() / "out";
  std::filesystem::create_directories(out);
  write_plan(out, plan);
  SweepRunOptions options;
  options.progress = false;
  run_sweep(out, plan, options);
  EXPECT_EQ(write_sweep_outputs(out, plan).missing, 0);
  auto rows = csv_rows(slurp(out / "sweep.csv"));
  EXPECT_EQ(rows.size(), points + 1);
  return rows.size() == points + 1 ? rows : std::vector<std::vector<std::string>>{};
}

}  // namespace hil::test
