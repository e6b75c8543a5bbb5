// Measurement files: strict about what it needs, tolerant of what it does not.
#include "hil/csv_reader.hpp"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include "temp_file.hpp"

using hil::CsvError;
using hil::CsvRequest;

namespace {

const CsvRequest kMeasurement{{"t_s", "theta_cmd_deg", "p_meas_mpa"}, {"theta_motor_deg"}, "t_s"};

std::string error_of(const std::string& text) {
  hil::test::TempDir dir;
  const auto file = dir.write("m.csv", text);
  try {
    (void)hil::read_csv(file, kMeasurement);
  } catch (const CsvError& e) {
    const std::string msg = e.what();
    return msg.substr(msg.find("m.csv"));
  }
  return "no error";
}

TEST(CsvReader, ReadsMetadataRequiredOptionalAndIgnoresOthers) {
  hil::test::TempDir dir;
  const auto file = dir.write("m.csv",
                              "# rig: lab 3\n# source: logger\n"
                              "t_s,comment_col,p_meas_mpa,theta_cmd_deg\n"
                              "0.000,anything,1.0,11.5\n"
                              "0.0013,  here ,1.1,+11.6\r\n"
                              "0.0021,x,1.2e0,11.7");  // no final newline, uneven steps
  hil::CsvHeader header;
  const auto data = hil::read_csv(file, kMeasurement, &header);
  ASSERT_EQ(data.rows(), 3u);
  EXPECT_EQ(header.metadata.size(), 2u);
  EXPECT_EQ(header.metadata[0].second, "lab 3");
  EXPECT_DOUBLE_EQ(data.values[0][2], 0.0021);
  EXPECT_DOUBLE_EQ(data.values[1][1], 11.6);
  EXPECT_DOUBLE_EQ(data.values[2][2], 1.2);
  EXPECT_FALSE(header.present[3]);  // no encoder column
  EXPECT_TRUE(data.values[3].empty());
  EXPECT_EQ(data.first_line, 4u);
}

TEST(CsvReader, MissingRequiredColumnNamesIt) {
  const auto msg = error_of("t_s,p_meas_mpa\n0,1\n");
  EXPECT_EQ(msg.rfind("m.csv:1:1: missing required column 'theta_cmd_deg'", 0), 0u) << msg;
}

TEST(CsvReader, NonNumericCellNamesLineAndColumn) {
  const auto msg = error_of("t_s,theta_cmd_deg,p_meas_mpa\n0,1,1\n0.001,1,abc\n");
  EXPECT_EQ(msg, "m.csv:3:3: column 'p_meas_mpa': not a number: 'abc'");
  EXPECT_EQ(error_of("t_s,theta_cmd_deg,p_meas_mpa\n0,,1\n"), "m.csv:2:2: column 'theta_cmd_deg': not a number: ''");
  EXPECT_NE(error_of("t_s,theta_cmd_deg,p_meas_mpa\n0,nan,1\n").find("m.csv:2:2"), std::string::npos);
}

TEST(CsvReader, TimeGoingBackwardsIsAnError) {
  const auto msg = error_of("t_s,theta_cmd_deg,p_meas_mpa\n0.001,1,1\n0.002,1,1\n0.0015,1,1\n");
  EXPECT_EQ(msg.rfind("m.csv:4:1: column 't_s': t_s goes backwards", 0), 0u) << msg;
}

TEST(CsvReader, RaggedRowAndEmptyFile) {
  EXPECT_EQ(error_of("t_s,theta_cmd_deg,p_meas_mpa\n0,1\n").rfind("m.csv:2:3: expected 3 fields", 0), 0u);
  EXPECT_EQ(error_of("").rfind("m.csv:1:1: no header row", 0), 0u);
  EXPECT_EQ(error_of("# only: metadata\n").rfind("m.csv:2:1: no header row", 0), 0u);
}

// What spreadsheet programs and old loggers write: a UTF-8 byte order mark is read past; lines
// ended by CR alone are refused by name (they read as one long line with a nonsense header).
TEST(CsvReader, AByteOrderMarkIsReadPastAndCrOnlyLineEndsAreNamed) {
  hil::test::TempDir dir;
  const auto file = dir.write("m.csv", "\xEF\xBB\xBFt_s,theta_cmd_deg,p_meas_mpa\n0,1,1\n0.001,1,1.5\n");
  const auto data = hil::read_csv(file, kMeasurement);
  ASSERT_EQ(data.rows(), 2u);
  EXPECT_DOUBLE_EQ(data.values[2][1], 1.5);
  EXPECT_EQ(error_of("t_s,theta_cmd_deg,p_meas_mpa\r0,1,1\r0.001,1,1.5\r"),
            "m.csv:1:29: a carriage return inside a line: the file's lines end in CR alone (old Mac style); save it with LF "
            "or CRLF line ends");
}

// Bytes from the file quoted in an error cannot cut the message (NUL) or drive the terminal (ESC).
TEST(CsvReader, ControlBytesInAQuotedCellAreShownEscaped) {
  const std::string nul_cell("t_s,theta_cmd_deg,p_meas_mpa\n0,1,1\n0.001,1,1\0x\x1b[2J\n", 51);
  EXPECT_EQ(error_of(nul_cell), "m.csv:3:3: column 'p_meas_mpa': not a number: '1\\x00x\\x1b[2J'");
  EXPECT_EQ(error_of("t_s,theta_cmd_deg,p_meas_mpa\n0,1," + std::string(100, '7') + "x\n"),
            "m.csv:2:3: column 'p_meas_mpa': not a number: '" + std::string(60, '7') + "...'");
}

// A file with no line ends (a binary, /dev/zero) is refused at 16 MiB, not read until memory ends.
TEST(CsvReader, ALineWithoutEndIsRefusedAt16MiB) {
  hil::test::TempDir dir;
  const auto file = dir.write("m.csv", "t_s,theta_cmd_deg,p_meas_mpa\n0,1,1\n" + std::string(17u << 20, '0'));
  try {
    (void)hil::read_csv(file, kMeasurement);
    FAIL() << "a 17 MiB line was read";
  } catch (const CsvError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("m.csv:3:1: a line longer than 16 MiB"), std::string::npos) << msg;
  }
  try {
    (void)hil::read_csv("/dev/zero", kMeasurement);
    FAIL() << "/dev/zero was read";
  } catch (const CsvError& e) {
    EXPECT_NE(std::string(e.what()).find("/dev/zero:1:1: a line longer than 16 MiB"), std::string::npos) << e.what();
  }
}

TEST(CsvReader, StreamsInChunks) {
  hil::test::TempDir dir;
  std::string text = "t_s,theta_cmd_deg,p_meas_mpa\n";
  for (int i = 0; i < 10000; ++i) text += std::to_string(i * 1e-3) + ",1," + std::to_string(1 + i * 1e-6) + "\n";
  const auto file = dir.write("big.csv", text);
  hil::CsvReader reader(file, kMeasurement);
  hil::CsvChunk chunk;
  std::size_t rows = 0, chunks = 0;
  while (reader.next(chunk, 3000)) rows += chunk.rows(), ++chunks;
  EXPECT_EQ(rows, 10000u);
  EXPECT_EQ(chunks, 4u);
  EXPECT_EQ(reader.bytes_read(), reader.file_bytes());
}

// Every row comes back whatever the file's size against the reader's pieces (a small file is read
// in one piece of its own size, a large one in 1 MiB pieces, lines crossing them), with or
// without a newline at the end, and from a pipe, whose size is not known.
TEST(CsvReader, EveryRowAtAnySizeAndFromAPipe) {
  hil::test::TempDir dir;
  auto file_of = [](std::size_t target_bytes, bool last_newline, std::size_t& rows) {
    std::string text = "t_s,theta_cmd_deg,p_meas_mpa\n";
    rows = 0;
    for (;;) {
      const std::string row = std::to_string(rows) + ",1,2.5";
      if (text.size() + row.size() + 1 > target_bytes) break;
      text += row + "\n";
      ++rows;
    }
    text += std::string(target_bytes - text.size() - 1, '#');  // a comment line pads to the size
    if (last_newline) text += "\n";
    return text;
  };
  for (const std::size_t bytes :
       {std::size_t{100}, std::size_t{4095}, std::size_t{4096}, std::size_t{4097}, std::size_t{(1 << 20) - 1},
        std::size_t{1 << 20}, std::size_t{(1 << 20) + 1}, std::size_t{(3 << 20) + 7}}) {
    for (const bool newline : {true, false}) {
      std::size_t rows = 0;
      const std::string text = file_of(bytes, newline, rows);
      const auto file = dir.write("sized.csv", text);
      hil::CsvReader reader(file, kMeasurement);
      hil::CsvChunk chunk;
      std::size_t got = 0;
      double last_t = -1;
      while (reader.next(chunk, 4000)) {
        got += chunk.rows();
        last_t = chunk.values[0].back();
      }
      EXPECT_EQ(got, rows) << bytes << " bytes";
      EXPECT_EQ(last_t, static_cast<double>(rows - 1)) << bytes << " bytes";
      EXPECT_EQ(reader.bytes_read(), text.size()) << bytes << " bytes";
    }
  }
  // A pipe: no size to go by.
  std::size_t rows = 0;
  const std::string text = file_of((1 << 20) + 4321, true, rows);
  const auto fifo = dir.path() / "fifo.csv";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::signal(SIGPIPE, SIG_IGN);  // a reader that stops early fails the test, not kills it
  std::thread writer([&] { std::ofstream(fifo, std::ios::binary) << text; });
  std::size_t got = 0;
  {
    hil::CsvReader reader(fifo, kMeasurement);
    hil::CsvChunk chunk;
    while (reader.next(chunk, 4000)) got += chunk.rows();
    EXPECT_EQ(reader.file_bytes(), 0u) << "a pipe's size is not known";
  }
  writer.join();
  EXPECT_EQ(got, rows);
}

// A file refused while its header is read (no header, duplicate or missing column) must not keep
// its descriptor: the reader's constructor throws, so no destructor closes it.
TEST(CsvReader, RefusedFilesAreClosed) {
  auto open_fds = [] {
    std::size_t n = 0;
    for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator("/proc/self/fd")) ++n;
    return n;
  };
  hil::test::TempDir dir;
  const auto no_header = dir.write("a.csv", "# only metadata\n");
  const auto twice = dir.write("b.csv", "t_s,t_s,p_meas_mpa\n0,0,1\n");
  const auto missing = dir.write("c.csv", "t_s,p_meas_mpa\n0,1\n");
  const std::size_t before = open_fds();
  for (int i = 0; i < 20; ++i) {
    for (const auto& f : {no_header, twice, missing}) EXPECT_THROW((void)hil::read_csv(f, kMeasurement), CsvError);
  }
  EXPECT_EQ(open_fds(), before);
}

}  // namespace
