// Whole files read into memory (configs, run records, sweep rows, uploads): the exact bytes, and
// every path that is not a readable regular file refused by name instead of misread or waited on.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <fstream>

#include "hil/text_file.hpp"
#include "temp_file.hpp"

namespace {

std::string error_of(const std::filesystem::path& file, std::string_view kind = "a file") {
  try {
    hil::read_text_file(file, kind);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "(read)";
}

TEST(TextFile, ReadsEveryByteAcrossChunksWithoutAddingOrDroppingAny) {
  hil::test::TempDir dir;
  // Longer than one 64 KiB read, with NULs, CRs and no final newline: nothing is text-mode'd.
  std::string bytes;
  for (int i = 0; i < 200000; ++i) bytes += static_cast<char>((i * 7919) % 256);
  bytes += "\r\nlast line without its newline";
  std::ofstream(dir.path() / "f.bin", std::ios::binary) << bytes;
  EXPECT_EQ(hil::read_text_file(dir.path() / "f.bin"), bytes);
  std::ofstream(dir.path() / "empty.yaml");
  EXPECT_EQ(hil::read_text_file(dir.path() / "empty.yaml"), "");
}

TEST(TextFile, AFolderIsNamedWithWhatWasExpected) {
  hil::test::TempDir dir;
  EXPECT_EQ(error_of(dir.path(), "a YAML file"), dir.path().string() + ": is a folder, not a YAML file");
}

TEST(TextFile, AMissingFileGivesTheSystemsReason) {
  hil::test::TempDir dir;
  EXPECT_EQ(error_of(dir.path() / "none.yaml"),
            (dir.path() / "none.yaml").string() + ": cannot open the file: No such file or directory");
}

TEST(TextFile, AFifoOrADeviceIsRefusedAtOnceNotWaitedOnOrReadForever) {
  hil::test::TempDir dir;
  // A FIFO with no writer: a plain open() would block this test until ctest's timeout.
  const auto fifo = dir.path() / "pipe.yaml";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_EQ(error_of(fifo), fifo.string() + ": is not a regular file");
  // /dev/zero never ends; read whole it would fill the memory.
  EXPECT_EQ(error_of("/dev/zero"), "/dev/zero: is not a regular file");
}

}  // namespace
