#include "hil/csv_writer.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <fstream>
#include <sstream>

TEST(CsvWriter, FixedDecimalsRoundLikeToChars) {
  const auto file = std::filesystem::temp_directory_path() / "hil_csv_fixed_test.csv";
  const double values[] = {0.0, -0.0, 1.5, -1.5, 0.001, -0.0004, 12345.6789, -987654321.123456, 1e300, -2.5e-7, 17.999};
  {
    hil::CsvWriter w(file, {{"a", 0}, {"b", 3}, {"c", 6}});
    for (double v : values) {
      const double row[] = {v, v, v};
      w.row(row);
    }
    w.close();
  }
  std::ifstream in(file);
  std::string line;
  std::getline(in, line);  // header
  for (double v : values) {
    std::getline(in, line);
    std::stringstream cells(line);
    std::string cell;
    for (int d : {0, 3, 6}) {
      std::getline(cells, cell, ',');
      // The text parses back to v within half a unit of the last digit.
      EXPECT_NEAR(std::stod(cell), v, 0.5000001 * std::pow(10.0, -d) + std::abs(v) * 1e-15) << cell;
      if (std::abs(v) >= 1e15) continue;  // written in its shortest exact form
      const auto dot = cell.find('.');
      EXPECT_EQ(d == 0 ? std::string::npos : cell.size() - dot - 1, d == 0 ? std::string::npos : std::size_t(d)) << cell;
    }
  }
  std::filesystem::remove(file);
}

TEST(CsvWriter, WritesMetadataHeaderAndFixedDecimals) {
  const auto file = std::filesystem::temp_directory_path() / "hil_csv_writer_test.csv";
  {
    hil::CsvWriter w(file, {{"t_s", 3}, {"p_meas_mpa", 6}}, {{"source", "test"}});
    const double r1[] = {0.001, 1.2345678};
    const double r2[] = {0.002, NAN};
    w.row(r1);
    w.row(r2);
    EXPECT_EQ(w.rows_written(), 2u);
    w.close();
  }
  std::ifstream in(file);
  std::stringstream ss;
  ss << in.rdbuf();
  EXPECT_EQ(ss.str(), "# source: test\nt_s,p_meas_mpa\n0.001,1.234568\n0.002,nan\n");
  std::filesystem::remove(file);
}
