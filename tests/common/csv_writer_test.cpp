#include "hil/csv_writer.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>

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
