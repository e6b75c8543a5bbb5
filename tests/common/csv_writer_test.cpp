#include "hil/csv_writer.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <system_error>
#include <thread>

#include "hil/line_file.hpp"
#include "small_disk.hpp"
#include "temp_file.hpp"

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

// On a full disk the file keeps whole lines only, and the writer says how many rows it lost.
TEST(CsvWriter, AFullDiskLeavesWholeRowsAndCountsTheRest) {
  hil::test::TempDir dir;
  hil::test::SmallDisk disk(dir.path() / "disk", "64k");
  if (!disk.mounted()) GTEST_SKIP() << "cannot mount a tmpfs here (not root?)";
  const auto file = dir.path() / "disk" / "t.csv";
  hil::CsvWriter w(file, {{"t_s", 3}, {"p_meas_mpa", 6}, {"padding", 6}});
  std::size_t handed = 0;
  bool refused = false;
  try {
    for (; handed < 100000; ++handed) {
      const double row[] = {handed * 1e-3, 1.234567, 123456.654321};
      w.row(row);
      if (handed % 100 == 99) w.flush();
    }
  } catch (const std::system_error& e) {
    refused = true;
    ++handed;  // the row whose flush failed was handed in
    EXPECT_NE(std::string(e.what()).find("No space left on device"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("t.csv"), std::string::npos) << e.what();
  }
  ASSERT_TRUE(refused);
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  const std::string s = text.str();
  ASSERT_FALSE(s.empty());
  EXPECT_EQ(s.back(), '\n');
  const auto lines = static_cast<std::size_t>(std::count(s.begin(), s.end(), '\n'));
  EXPECT_EQ(lines - 1, w.rows_on_disk());  // the header, then every row on disk
  EXPECT_EQ(w.rows_on_disk() + w.rows_dropped(), handed);
  EXPECT_EQ(w.rows_written(), handed);
  EXPECT_GT(w.rows_dropped(), 0u);
}

TEST(LineFile, TrimsAHalfWrittenLastLine) {
  hil::test::TempDir dir;
  const auto file = dir.write("x.jsonl", "{\"a\":1}\n{\"b\":2}\n{\"c\":");
  EXPECT_EQ(hil::trim_to_whole_lines(file), 5u);
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(text.str(), "{\"a\":1}\n{\"b\":2}\n");
  EXPECT_EQ(hil::trim_to_whole_lines(file), 0u);
  hil::LineFile f(file, /*append=*/true);
  f.append("{\"d\":4}\n");
  EXPECT_EQ(f.bytes(), 24u);
}

namespace {
std::string slurp(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}
std::size_t entries(const std::filesystem::path& dir) {
  return static_cast<std::size_t>(std::distance(std::filesystem::directory_iterator(dir), {}));
}
}  // namespace

TEST(ReplaceFile, WritesThePartsInOrderAndLeavesNoTemporary) {
  hil::test::TempDir dir;
  const auto file = dir.write("r.json", "old\n");
  const std::string_view parts[] = {"{\"a\":", "", "1}\n"};
  hil::replace_file(file, parts);
  EXPECT_EQ(slurp(file), "{\"a\":1}\n");
  EXPECT_EQ(entries(dir.path()), 1u);
}

// Two writers of one file (two `sim --out` of one folder, two threads of a server) each get
// their own temporary, so the file is always one writer's whole text; with one shared
// temporary name they wrote into each other's file and one rename found it gone.
TEST(ReplaceFile, TwoWritersOfOneFileLeaveOneWholeText) {
  hil::test::TempDir dir;
  const auto file = dir.path() / "summary.json";
  const std::string long_text(200000, 'a'), short_text = "short\n";
  std::atomic<int> failures{0};
  auto writer = [&](const std::string& text) {
    for (int i = 0; i < 200; ++i) {
      try {
        hil::replace_file(file, text);
      } catch (const std::system_error&) {
        ++failures;
      }
    }
  };
  std::thread a(writer, std::cref(long_text)), b(writer, std::cref(short_text));
  int torn = 0;
  for (int i = 0; i < 200; ++i) {
    const std::string seen = slurp(file);
    if (!seen.empty() && seen != long_text && seen != short_text) ++torn;
  }
  a.join();
  b.join();
  EXPECT_EQ(failures.load(), 0);
  EXPECT_EQ(torn, 0);
  const std::string last = slurp(file);
  EXPECT_TRUE(last == long_text || last == short_text) << last.size() << " bytes";
  EXPECT_EQ(entries(dir.path()), 1u);
}

TEST(ReplaceFile, AFullDiskKeepsTheOldFileAndNamesTheReason) {
  hil::test::TempDir dir;
  hil::test::SmallDisk disk(dir.path() / "disk", "64k");
  if (!disk.mounted()) GTEST_SKIP() << "cannot mount a tmpfs here (not root?)";
  const auto file = dir.path() / "disk" / "run.json";
  hil::replace_file(file, "{\"state\":\"running\"}\n");
  try {
    hil::replace_file(file, std::string(128 * 1024, 'x'));
    FAIL() << "128 KiB should not fit on a 64 KiB disk";
  } catch (const std::system_error& e) {
    EXPECT_NE(std::string(e.what()).find("No space left on device"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
  }
  EXPECT_EQ(slurp(file), "{\"state\":\"running\"}\n");
  EXPECT_EQ(entries(dir.path() / "disk"), 1u);
}

TEST(ReplaceFile, AMissingFolderIsNamed) {
  try {
    hil::replace_file("/nonexistent-hil-folder/run.json", "x\n");
    FAIL() << "should throw";
  } catch (const std::system_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-hil-folder/run.json"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("No such file or directory"), std::string::npos) << e.what();
  }
}

TEST(ReplaceFile, KeepsThePermissionsOfTheFileItReplaces) {
  hil::test::TempDir dir;
  const auto file = dir.write("README.md", "old\n");
  std::filesystem::permissions(file, std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
  hil::replace_file(file, "new\n");
  EXPECT_EQ(slurp(file), "new\n");
  EXPECT_EQ(std::filesystem::status(file).permissions() & std::filesystem::perms::all,
            std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
}

// A result of several files (compare.json and report.html) is replaced together: when the disk
// takes the first and not the second, both stay as they were (never a new JSON beside an old
// report, which is what compare left on a full disk).
TEST(ReplaceFile, SeveralFilesAreReplacedAllOrNone) {
  hil::test::TempDir dir;
  hil::test::SmallDisk disk(dir.path() / "disk", "64k");
  if (!disk.mounted()) GTEST_SKIP() << "cannot mount a tmpfs here (not root?)";
  const auto json = dir.path() / "disk" / "compare.json", html = dir.path() / "disk" / "report.html";
  hil::replace_files(std::vector<hil::FileText>{{json, {"old json\n"}}, {html, {"old report\n"}}});
  const std::string new_json = "new json\n", big_report(128 * 1024, 'r');
  EXPECT_THROW(hil::replace_files(std::vector<hil::FileText>{{json, {new_json}}, {html, {big_report}}}), std::system_error);
  EXPECT_EQ(slurp(json), "old json\n");
  EXPECT_EQ(slurp(html), "old report\n");
  EXPECT_EQ(entries(dir.path() / "disk"), 2u);
  hil::replace_files(std::vector<hil::FileText>{{json, {new_json}}, {html, {"new ", "report\n"}}});
  EXPECT_EQ(slurp(json), "new json\n");
  EXPECT_EQ(slurp(html), "new report\n");
}
