// What the MCAP writer, reader and finisher share inside hil_common: the magic, the opcodes, the
// spec's little-endian framing (writing and a bounds-checked reading cursor), and zstd chunk
// compression (Debian's libzstd). Not installed: hil/mcap.hpp is the interface.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <utility>

#include "hil/mcap.hpp"

namespace hil::mcap::detail {

constexpr std::string_view kMagic("\x89MCAP0\r\n", 8);
// A chunk's records, decompressed, are at most this large: a hostile uncompressed_size allocates
// nothing beyond it (other writers' chunks are a few MiB; ours at most chunk_bytes).
constexpr std::uint64_t kMaxChunkRecordsBytes = 256ull << 20;

// Opcodes (spec, "Records").
enum Op : std::uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kAttachment = 0x09,
  kAttachmentIndex = 0x0A,
  kStatistics = 0x0B,
  kMetadata = 0x0C,
  kMetadataIndex = 0x0D,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};

// Little-endian fields, strings and maps as the spec's "Serialization" section has them.
inline void u8(std::string& o, std::uint8_t v) { o.push_back(static_cast<char>(v)); }
template <class T>
void le(std::string& o, T v) {
  for (std::size_t i = 0; i < sizeof(T); ++i) o.push_back(static_cast<char>((static_cast<std::uint64_t>(v) >> (8 * i)) & 0xff));
}
inline void str(std::string& o, std::string_view s) {
  le<std::uint32_t>(o, static_cast<std::uint32_t>(s.size()));
  o.append(s);
}
template <class V>
void id_map(std::string& o, const std::map<std::uint16_t, V>& m) {
  std::string body;
  for (const auto& [k, v] : m) le<std::uint16_t>(body, k), le<std::uint64_t>(body, v);
  str(o, body);
}
inline std::string framed(std::uint8_t opcode, std::string_view body) {
  std::string r;
  r.reserve(9 + body.size());
  u8(r, opcode);
  le<std::uint64_t>(r, body.size());
  r.append(body);
  return r;
}

// A bounds-checked cursor over a record's body: every read past its end returns false (the
// caller words it as "field X runs past the record's end"), never reads out of bounds.
struct Fields {
  std::string_view b;
  std::size_t pos = 0;
  const char* record;  // its name, for the message
  std::string short_of(const char* field) const {
    return std::string(record) + " record: field '" + field + "' runs past the record's end";
  }
  template <class T>
  bool num(T& v) {
    if (b.size() - pos < sizeof(T)) return false;
    std::uint64_t x = 0;
    for (std::size_t i = 0; i < sizeof(T); ++i) x |= static_cast<std::uint64_t>(static_cast<std::uint8_t>(b[pos + i])) << (8 * i);
    v = static_cast<T>(x), pos += sizeof(T);
    return true;
  }
  bool bytes(std::uint64_t n, std::string_view& out) {
    if (b.size() - pos < n) return false;
    out = b.substr(pos, n), pos += n;
    return true;
  }
  bool str(std::string_view& out) {
    std::uint32_t n = 0;
    return num(n) && bytes(n, out);
  }
  bool str(std::string& out) {
    std::string_view v;
    if (!str(v)) return false;
    out.assign(v);
    return true;
  }
  bool kv(KeyValues& out) {
    std::string_view m;
    if (!str(m)) return false;
    Fields inner{m, 0, record};
    while (inner.pos < m.size()) {
      std::string k, v;
      if (!inner.str(k) || !inner.str(v)) return false;
      out.emplace_back(std::move(k), std::move(v));
    }
    return true;
  }
};

// A chunk record's fields (spec, "Chunk"); `records` points into the record's body.
struct ChunkFields {
  std::uint64_t start_ns = 0, end_ns = 0, uncompressed_size = 0;
  std::uint32_t crc = 0;
  std::string_view compression, records;
};
// Parses a chunk's body; "" when whole, else what is wrong.
std::string parse_chunk(std::string_view body, ChunkFields& c);
// The chunk's records, uncompressed, into out (checked against uncompressed_size and the CRC);
// "" when whole, else what is wrong ("chunk compressed with 'lz4': ..."). Bounded by
// kMaxChunkRecordsBytes whatever the chunk claims.
std::string chunk_records(const ChunkFields& c, std::string& out);

// zstd (level kZstdLevel) of `in`, appended to out; throws McapError naming `file` if it fails.
constexpr int kZstdLevel = 3;
void zstd_compress(std::string_view in, std::string& out, const std::string& file);

}  // namespace hil::mcap::detail
