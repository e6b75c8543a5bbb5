// A time range of a telemetry.csv at full resolution (server/telemetry_range.hpp), against files
// written here: the rows in the range, exactly, wherever the range falls in a file of 200 000 rows
// (the bisection on byte offsets against a count of the rows written); the edges; a last line
// being written; the bound on rows; unknown and absent columns; files that are no telemetry.csv.
#include <fcntl.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "hil/bench/server/runner.hpp"
#include "server/telemetry_range.hpp"

namespace {

using hil::bench::TelemetryRange;
using nlohmann::json;

struct File {
  std::filesystem::path path;
  explicit File(const std::string& text) {
    path =
        std::filesystem::temp_directory_path() / ("hil_range_" + std::to_string(::getpid()) + "_" + std::to_string(counter()++));
    std::ofstream(path, std::ios::binary) << text;
  }
  ~File() { std::filesystem::remove(path); }
  static int& counter() {
    static int n = 0;
    return n;
  }
  json range(TelemetryRange q) const {
    const int fd = ::open(path.c_str(), O_RDONLY);
    const auto size = std::filesystem::file_size(path);
    try {
      const std::string text = hil::bench::telemetry_range_json(fd, size, "t.csv", q);
      ::close(fd);
      return json::parse(text);
    } catch (...) {
      ::close(fd);
      throw;
    }
  }
};

// The recorder's shape: comment lines, the header, rows at 1 kHz (t_s with 4 decimals).
std::string telemetry(int rows) {
  std::string s = "# campaign: x\n# rig: sim\nt_s,theta_cmd_deg,p_meas_mpa\n";
  char line[96];
  for (int k = 0; k < rows; ++k) {
    std::snprintf(line, sizeof line, "%.4f,%.5f,%.6f\n", k * 0.001, std::sin(k * 0.01), 1.0 + k * 1e-6);
    s += line;
  }
  return s;
}

TelemetryRange q(double a, double b, std::vector<std::string> cols = {"p_meas_mpa"}, std::uint64_t max_rows = 20000) {
  return TelemetryRange{a, b, std::move(cols), max_rows};
}

TEST(TelemetryRange, EveryRowOfTheRangeWhereverItFalls) {
  const File f(telemetry(200000));
  for (const double a : {0.0, 0.0005, 1.2345, 57.0, 99.999, 150.5, 199.9}) {
    const double b = a + 0.25;
    const json j = f.range(q(a, b, {"p_meas_mpa", "theta_cmd_deg"}));
    // Rows k with a <= k/1000 <= b, as the file's 4-decimal times read back.
    std::vector<int> want;
    char text[32];
    for (int k = 0; k < 200000; ++k) {
      std::snprintf(text, sizeof text, "%.4f", k * 0.001);
      const double t = std::stod(text);
      if (t >= a && t <= b) want.push_back(k);
    }
    ASSERT_EQ(j["rows"], want.size()) << "from " << a;
    ASSERT_EQ(j["t_s"].size(), want.size());
    for (std::size_t i = 0; i < want.size(); ++i) {
      std::snprintf(text, sizeof text, "%.6f", 1.0 + want[i] * 1e-6);
      ASSERT_EQ(j["columns"]["p_meas_mpa"][i].get<double>(), std::stod(text)) << "row " << want[i];
    }
    EXPECT_EQ(j["columns"]["theta_cmd_deg"].size(), want.size());
  }
}

TEST(TelemetryRange, EdgesAndALineBeingWritten) {
  const File f(telemetry(5000));
  EXPECT_EQ(f.range(q(-10, -1))["rows"], 0);
  EXPECT_EQ(f.range(q(4.999, 100))["rows"], 1);
  EXPECT_EQ(f.range(q(0, 0))["rows"], 1);
  // A last line without its newline is being written: not yet a row.
  const File partial(telemetry(100) + "0.1000,0.5,1.00");
  EXPECT_EQ(partial.range(q(0.09, 1))["rows"], 10);
}

TEST(TelemetryRange, BoundedUnknownAndAbsentColumns) {
  const File f(telemetry(5000));
  try {
    f.range(q(0, 5, {"p_meas_mpa"}, 100));
    FAIL() << "5000 rows returned under max_rows 100";
  } catch (const hil::bench::BadField& e) {
    EXPECT_EQ(e.field, "to_s");
    EXPECT_NE(std::string(e.what()).find("more than 100 rows"), std::string::npos) << e.what();
  }
  EXPECT_EQ(f.range(q(0, 0.0995, {"p_meas_mpa"}, 100))["rows"], 100);
  try {
    f.range(q(0, 1, {"p_meas_mp"}));
    FAIL() << "an unknown column was accepted";
  } catch (const hil::bench::BadField& e) {
    EXPECT_EQ(e.field, "columns");
    EXPECT_NE(std::string(e.what()).find("did you mean 'p_meas_mpa'"), std::string::npos) << e.what();
  }
  const json j = f.range(q(0, 0.01, {"gap_true_deg", "p_meas_mpa", "p_meas_mpa", "t_s"}));
  EXPECT_EQ(j["absent"], json::array({"gap_true_deg"}));
  EXPECT_EQ(j["columns"].size(), 1u);
}

TEST(TelemetryRange, FilesThatAreNoTelemetry) {
  const File none("# only a comment\n");
  EXPECT_THROW(none.range(q(0, 1)), std::runtime_error);
  const File other("time,p\n0,1\n");
  EXPECT_THROW(other.range(q(0, 1)), std::runtime_error);
  const File long_line("t_s,p_meas_mpa\n0," + std::string(70000, '1') + "\n");
  try {
    long_line.range(q(0, 1));
    FAIL() << "a 70 kB line was read";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("a line longer than 64 KiB"), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).rfind("t.csv: byte ", 0), 0u) << e.what();
  }
  // A cell that is no number is null, not a crash.
  const File junk("t_s,p_meas_mpa\n0.0,abc\n0.001,\n0.002,1e999\n");
  const json j = junk.range(q(0, 1));
  EXPECT_EQ(j["columns"]["p_meas_mpa"], json::array({nullptr, nullptr, nullptr}));
}

}  // namespace
