// hil::mcap: zstd chunks read back as uncompressed ones are, and Writer::finish giving a file
// whose writer died its summary and footer. The files' framing is walked here by the spec
// (opcode u8, length u64 LE), independently of the reader; @mcap/core reads the bench's files
// in tests/mcap.
#include <gtest/gtest.h>

#include <fstream>

#include "hil/mcap.hpp"
#include "temp_file.hpp"

namespace {

using hil::mcap::Compression;

std::string slurp(const std::filesystem::path& f) {
  std::ifstream in(f, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
void spit(const std::filesystem::path& f, const std::string& bytes) { std::ofstream(f, std::ios::binary) << bytes; }
std::uint64_t le64(const std::string& b, std::size_t at) {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(static_cast<unsigned char>(b[at + i])) << (8 * i);
  return v;
}

// Top-level records: (opcode, offset, length with framing); stops where a record runs past the end.
std::vector<std::tuple<int, std::uint64_t, std::uint64_t>> records(const std::string& b) {
  std::vector<std::tuple<int, std::uint64_t, std::uint64_t>> out;
  for (std::uint64_t at = 8; at + 9 <= b.size() && at + 9 + le64(b, at + 1) <= b.size(); at += 9 + le64(b, at + 1))
    out.emplace_back(static_cast<unsigned char>(b[at]), at, 9 + le64(b, at + 1));
  return out;
}

// Rows of JSON on two channels, as the recorder writes them, in chunks of ~chunk bytes; a metadata
// record after the first rows.
void write_file(const std::filesystem::path& file, Compression c, std::size_t rows, std::size_t chunk = 8192) {
  hil::mcap::Writer w(file, "", chunk, c);
  const auto s = w.add_schema("t", "jsonschema", R"({"type":"object"})");
  const auto rows_ch = w.add_channel(s, "/rows", "json"), events_ch = w.add_channel(s, "/events", "json");
  for (std::size_t i = 0; i < rows; ++i) {
    w.message(rows_ch, 1'700'000'000'000'000'000ull + i * 1'000'000,
              R"({"t_s":)" + std::to_string(i * 1e-3) + R"(,"p_meas_mpa":1.5000,"theta_cmd_deg":12.25})");
    if (i % 97 == 0) w.message(events_ch, 1'700'000'000'000'000'000ull + i * 1'000'000, R"({"kind":"overrun"})");
    if (i == 10) w.metadata("campaign", {{"yaml", "name: x\n"}});
  }
  w.close();
}

struct Read {
  std::vector<std::string> data;
  std::vector<std::uint64_t> times;
  bool truncated = false;
};
Read read_all(const std::filesystem::path& file) {
  hil::mcap::Reader r(file);
  hil::mcap::Message m;
  Read out;
  while (r.next(m)) out.data.emplace_back(m.data), out.times.push_back(m.log_time_ns);
  out.truncated = r.truncated();
  return out;
}

std::string error_of(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(Mcap, ZstdChunksReadBackAsUncompressedOnesAndAreSmaller) {
  hil::test::TempDir dir;
  write_file(dir.path() / "plain.mcap", Compression::none, 3000);
  write_file(dir.path() / "zstd.mcap", Compression::zstd, 3000);
  const Read plain = read_all(dir.path() / "plain.mcap"), zstd = read_all(dir.path() / "zstd.mcap");
  ASSERT_EQ(plain.data.size(), 3000u + 31);
  EXPECT_EQ(zstd.data, plain.data);
  EXPECT_EQ(zstd.times, plain.times);
  EXPECT_FALSE(zstd.truncated);
  // Every chunk says zstd, and the summary's chunk indexes give both sizes.
  const std::string b = slurp(dir.path() / "zstd.mcap");
  std::size_t chunks = 0;
  for (const auto& [op, at, len] : records(b)) {
    if (op != 0x06) continue;
    ++chunks;
    EXPECT_EQ(b.substr(at + 9 + 28, 8), std::string("\x04\0\0\0zstd", 8)) << "compression field of the chunk at " << at;
  }
  EXPECT_GT(chunks, 3u);
  EXPECT_LT(b.size() * 3, slurp(dir.path() / "plain.mcap").size()) << "JSON rows compress well";
}

TEST(Mcap, DamagedOrHostileZstdChunksAreClearErrorsNamingTheChunk) {
  hil::test::TempDir dir;
  write_file(dir.path() / "good.mcap", Compression::zstd, 2000);
  const std::string b = slurp(dir.path() / "good.mcap");
  std::uint64_t chunk_at = 0, chunk_len = 0;
  for (const auto& [op, at, len] : records(b))
    if (op == 0x06 && chunk_at == 0) chunk_at = at, chunk_len = len;
  ASSERT_GT(chunk_at, 0u);
  const auto read_error = [&](const std::string& bytes) {
    spit(dir.path() / "bad.mcap", bytes);
    return error_of([&] { read_all(dir.path() / "bad.mcap"); });
  };
  // A byte of the compressed records flipped: zstd or the CRC of the records says so.
  std::string flipped = b;
  flipped[chunk_at + chunk_len - 20] ^= 0x10;
  const std::string e1 = read_error(flipped);
  EXPECT_NE(e1.find("record at byte " + std::to_string(chunk_at) + ": chunk"), std::string::npos) << e1;
  // An uncompressed_size beyond the bound: refused before anything is allocated.
  std::string huge = b;
  for (int i = 0; i < 8; ++i) huge[chunk_at + 9 + 16 + i] = i == 7 ? '\x7f' : '\xff';
  const std::string e2 = read_error(huge);
  EXPECT_NE(e2.find("is beyond what this reader takes"), std::string::npos) << e2;
  // A size smaller than what the records decompress to.
  std::string small = b;
  for (int i = 0; i < 8; ++i) small[chunk_at + 9 + 16 + i] = i == 0 ? '\x10' : '\0';
  const std::string e3 = read_error(small);
  EXPECT_NE(e3.find("decompress to more than the chunk's uncompressed_size"), std::string::npos) << e3;
  // Another compression: named.
  std::string lz4 = b;
  lz4.replace(chunk_at + 9 + 28 + 4, 4, "lz4!");
  const std::string e4 = read_error(lz4);
  EXPECT_NE(e4.find("chunk compressed with 'lz4!'"), std::string::npos) << e4;
}

// A file cut at every kind of place a kill -9 can leave it: inside a chunk, between a chunk and
// its message indexes, inside those, inside the summary. finish() gives each its summary and
// footer; it then reads as the whole messages it held, and a second finish() changes nothing.
TEST(Mcap, FinishGivesACutFileItsSummaryAndFooterAndKeepsEveryWholeChunk) {
  hil::test::TempDir dir;
  write_file(dir.path() / "whole.mcap", Compression::zstd, 4000, 4096);
  const std::string b = slurp(dir.path() / "whole.mcap");
  const auto recs = records(b);
  std::vector<std::pair<std::string, std::uint64_t>> cuts;  // what, where
  std::uint64_t data_end = 0;
  std::size_t chunk_no = 0;
  for (std::size_t i = 0; i < recs.size(); ++i) {
    const auto [op, at, len] = recs[i];
    if (op == 0x06 && ++chunk_no == 5) {
      cuts.push_back({"inside chunk 5", at + len / 2});
      cuts.push_back({"after chunk 5, before its indexes", at + len});
      cuts.push_back({"inside chunk 5's first message index", at + len + 12});
      ASSERT_EQ(std::get<0>(recs[i + 1]), 0x07);
      cuts.push_back({"after chunk 5's first message index", at + len + std::get<2>(recs[i + 1])});
    }
    if (op == 0x0F) data_end = at;
  }
  ASSERT_GT(data_end, 0u);
  cuts.push_back({"inside the summary", data_end + 13 + 40});
  cuts.push_back({"before the closing magic", b.size() - 8});
  const Read whole = read_all(dir.path() / "whole.mcap");
  for (const auto& [what, at] : cuts) {
    SCOPED_TRACE(what);
    const auto file = dir.path() / "cut.mcap";
    spit(file, b.substr(0, at));
    const Read before = read_all(file);  // the stream reader's view of the cut file
    const hil::mcap::Finished f = hil::mcap::Writer::finish(file);
    EXPECT_FALSE(f.was_whole);
    const std::string after = slurp(file);
    ASSERT_EQ(after.substr(after.size() - 8), b.substr(0, 8)) << "the closing magic";
    EXPECT_EQ(after[after.size() - 8 - 29], '\x02') << "the footer";
    const Read r = read_all(file);
    EXPECT_FALSE(r.truncated);
    EXPECT_EQ(r.data, before.data) << "every message of the whole chunks, no more";
    EXPECT_EQ(f.messages, r.data.size());
    EXPECT_GT(r.data.size(), 100u);
    EXPECT_TRUE(std::equal(r.data.begin(), r.data.end(), whole.data.begin()));
    // The summary's statistics and chunk indexes, walked: Data End, then the summary groups.
    const auto rs = records(after);
    std::size_t chunks = 0, indexes = 0, stats = 0;
    for (const auto& [op, rat, len] : rs) chunks += op == 0x06, indexes += op == 0x08, stats += op == 0x0B;
    EXPECT_EQ(indexes, chunks) << "a chunk index per chunk";
    EXPECT_EQ(stats, 1u);
    EXPECT_EQ(f.chunks, chunks);
    EXPECT_EQ(le64(after, std::get<1>(*std::find_if(rs.begin(), rs.end(), [](auto& x) { return std::get<0>(x) == 0x0B; })) + 9),
              r.data.size())
        << "the statistics' message count";
    const hil::mcap::Finished again = hil::mcap::Writer::finish(file);
    EXPECT_TRUE(again.was_whole);
    EXPECT_EQ(slurp(file), after);
  }
  // A whole file is left as it is.
  EXPECT_TRUE(hil::mcap::Writer::finish(dir.path() / "whole.mcap").was_whole);
  EXPECT_EQ(slurp(dir.path() / "whole.mcap"), b);
}

TEST(Mcap, FinishLeavesAFileItCannotFinishUntouched) {
  hil::test::TempDir dir;
  write_file(dir.path() / "whole.mcap", Compression::zstd, 3000, 4096);
  const std::string b = slurp(dir.path() / "whole.mcap");
  std::uint64_t second_chunk = 0;
  std::size_t n = 0;
  for (const auto& [op, at, len] : records(b))
    if (op == 0x06 && ++n == 2) second_chunk = at;
  // A damaged chunk (a whole record, not a cut one): nothing whole is removed.
  std::string damaged = b.substr(0, b.size() - 200);
  damaged[second_chunk + 9 + 8] ^= 0x01;  // its end time: the CRC is of the records, so change the size
  damaged[second_chunk + 9 + 16] ^= 0x01;
  spit(dir.path() / "damaged.mcap", damaged);
  const std::string e = error_of([&] { hil::mcap::Writer::finish(dir.path() / "damaged.mcap"); });
  EXPECT_NE(e.find("record at byte " + std::to_string(second_chunk)), std::string::npos) << e;
  EXPECT_NE(e.find("the file is left as it is"), std::string::npos) << e;
  EXPECT_EQ(slurp(dir.path() / "damaged.mcap"), damaged);
  // Not an MCAP file, and a file with no whole header.
  spit(dir.path() / "text.mcap", "t_s,p\n0,1\n");
  EXPECT_NE(error_of([&] { hil::mcap::Writer::finish(dir.path() / "text.mcap"); }).find("not an MCAP file"), std::string::npos);
  EXPECT_EQ(slurp(dir.path() / "text.mcap"), "t_s,p\n0,1\n");
  spit(dir.path() / "magic_only.mcap", b.substr(0, 12));
  EXPECT_NE(error_of([&] { hil::mcap::Writer::finish(dir.path() / "magic_only.mcap"); }).find("no whole MCAP header"),
            std::string::npos);
  EXPECT_EQ(slurp(dir.path() / "magic_only.mcap"), b.substr(0, 12));
  EXPECT_NE(error_of([&] { hil::mcap::Writer::finish(dir.path() / "absent.mcap"); }).find("cannot open"), std::string::npos);
}
