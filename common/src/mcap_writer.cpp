#include <array>
#include <cerrno>
#include <cstring>

#include "hil/mcap.hpp"
#include "mcap_internal.hpp"

namespace hil::mcap {

using namespace detail;

namespace {

void kv_map(std::string& o, const KeyValues& m) {
  std::string body;
  for (const auto& [k, v] : m) str(body, k), str(body, v);
  str(o, body);  // a map is its byte length, then the pairs
}

}  // namespace

std::uint32_t crc32(std::string_view data, std::uint32_t crc) {
  static const auto kTable = [] {
    std::array<std::uint32_t, 256> t{};
    for (std::uint32_t i = 0; i < 256; ++i) {
      std::uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  crc = ~crc;
  for (const char ch : data) crc = kTable[(crc ^ static_cast<std::uint8_t>(ch)) & 0xff] ^ (crc >> 8);
  return ~crc;
}

Writer::Writer(const std::filesystem::path& file, std::string_view profile, std::size_t chunk_bytes, Compression compression)
    : path_(file), chunk_bytes_(chunk_bytes), compression_(compression) {
  f_ = std::fopen(file.c_str(), "wb");
  if (f_ == nullptr) throw McapError(file.string() + ": cannot create: " + std::strerror(errno));
  put(kMagic);
  std::string h;
  str(h, profile);
  str(h, "hilbench");
  record(kHeader, h);
}

Writer::~Writer() {
  if (f_ == nullptr) return;
  try {
    if (!failed_) close();
  } catch (...) {  // the destructor of a failed writer: the file keeps what is whole
  }
  if (f_ != nullptr) std::fclose(f_), f_ = nullptr;
}

void Writer::put(std::string_view bytes) {
  if (f_ == nullptr) throw McapError(path_.string() + ": written after close");
  if (std::fwrite(bytes.data(), 1, bytes.size(), f_) != bytes.size()) {
    failed_ = true;
    throw McapError(path_.string() + ": cannot write: " + std::strerror(errno));
  }
  offset_ += bytes.size();
}

std::uint64_t Writer::record(std::uint8_t opcode, std::string_view body) {
  const std::uint64_t at = offset_;
  put(framed(opcode, body));
  return at;
}

std::uint16_t Writer::add_schema(std::string_view name, std::string_view encoding, std::string_view data) {
  std::string b;
  const auto id = static_cast<std::uint16_t>(schemas_.size() + 1);
  le<std::uint16_t>(b, id);
  str(b, name), str(b, encoding), str(b, data);
  record(kSchema, b);
  schemas_.push_back(std::move(b));
  return id;
}

std::uint16_t Writer::add_channel(std::uint16_t schema_id, std::string_view topic, std::string_view message_encoding,
                                  const KeyValues& metadata) {
  std::string b;
  const auto id = static_cast<std::uint16_t>(channels_.size() + 1);
  le<std::uint16_t>(b, id), le<std::uint16_t>(b, schema_id);
  str(b, topic), str(b, message_encoding);
  kv_map(b, metadata);
  record(kChannel, b);
  channels_.push_back(std::move(b));
  sequence_.push_back(0);
  return id;
}

void Writer::message(std::uint16_t channel_id, std::uint64_t log_time_ns, std::string_view data) {
  if (channel_id == 0 || channel_id > channels_.size()) throw McapError(path_.string() + ": message on an unknown channel");
  std::string b;
  b.reserve(22 + data.size());
  le<std::uint16_t>(b, channel_id);
  le<std::uint32_t>(b, sequence_[channel_id - 1]++);
  le<std::uint64_t>(b, log_time_ns), le<std::uint64_t>(b, log_time_ns);
  b.append(data);
  std::string& index = chunk_index_[channel_id];
  le<std::uint64_t>(index, log_time_ns), le<std::uint64_t>(index, chunk_.size());
  if (chunk_.empty() || log_time_ns < chunk_start_ns_) chunk_start_ns_ = log_time_ns;
  if (chunk_.empty() || log_time_ns > chunk_end_ns_) chunk_end_ns_ = log_time_ns;
  count_message(channel_id, log_time_ns);
  chunk_ += framed(kMessage, b);
  if (chunk_.size() >= chunk_bytes_) flush_chunk();
}

void Writer::flush_chunk() {
  if (!chunk_.empty()) {
    const bool zstd = compression_ == Compression::zstd;
    std::string b;
    le<std::uint64_t>(b, chunk_start_ns_), le<std::uint64_t>(b, chunk_end_ns_);
    le<std::uint64_t>(b, chunk_.size());
    le<std::uint32_t>(b, crc32(chunk_));  // of the uncompressed records
    str(b, zstd ? "zstd" : "");
    const std::size_t size_at = b.size();
    le<std::uint64_t>(b, 0);  // the records' length, known once they are in
    if (zstd)
      zstd_compress(chunk_, b, path_.string());
    else
      b += chunk_;
    const std::uint64_t records_bytes = b.size() - size_at - 8;
    for (std::size_t i = 0; i < 8; ++i) b[size_at + i] = static_cast<char>((records_bytes >> (8 * i)) & 0xff);
    ChunkIndex ci{chunk_start_ns_, chunk_end_ns_, 0, 0, 0, records_bytes, chunk_.size(), zstd ? "zstd" : "", {}};
    // One write for the chunk and its indexes: a crash leaves it whole or cut, never interleaved.
    std::string out = framed(kChunk, b);
    ci.offset = offset_, ci.length = out.size();
    for (const auto& [channel, entries] : chunk_index_) {
      ci.index_offsets[channel] = offset_ + out.size();
      const std::string r = message_index(channel, entries);
      ci.index_length += r.size();
      out += r;
    }
    put(out);
    chunks_.push_back(std::move(ci));
    chunk_.clear(), chunk_index_.clear();
  }
  if (f_ != nullptr && std::fflush(f_) != 0) {
    failed_ = true;
    throw McapError(path_.string() + ": cannot write: " + std::strerror(errno));
  }
}

std::string Writer::message_index(std::uint16_t channel, std::string_view entries) {
  std::string mi;
  le<std::uint16_t>(mi, channel);
  str(mi, entries);
  return framed(kMessageIndex, mi);
}

void Writer::metadata(std::string_view name, const KeyValues& values) {
  flush_chunk();
  std::string b;
  str(b, name);
  kv_map(b, values);
  const std::uint64_t at = record(kMetadata, b);
  metadata_.push_back({at, {offset_ - at, std::string(name)}});
}

void Writer::attachment(std::string_view name, std::string_view media_type, std::string_view data, std::uint64_t log_time_ns) {
  flush_chunk();
  std::string b;
  le<std::uint64_t>(b, log_time_ns), le<std::uint64_t>(b, 0);  // create time unknown: zero
  str(b, name), str(b, media_type);
  le<std::uint64_t>(b, data.size());
  b.append(data);
  le<std::uint32_t>(b, crc32(b));  // over the fields before it
  const std::uint64_t at = record(kAttachment, b);
  attachments_.push_back({at, offset_ - at, log_time_ns, data.size(), std::string(name), std::string(media_type)});
}

void Writer::close() {
  if (f_ == nullptr) return;
  flush_chunk();
  std::string de;
  le<std::uint32_t>(de, 0);  // the data section's CRC is not kept: every chunk and the summary carry their own
  record(kDataEnd, de);

  // The summary: groups of one opcode each, then a Summary Offset per group.
  const std::uint64_t summary_start = offset_;
  std::string summary;
  std::vector<std::pair<std::uint8_t, std::pair<std::uint64_t, std::uint64_t>>> groups;
  auto group = [&](std::uint8_t op, const std::vector<std::string>& bodies) {
    if (bodies.empty()) return;
    const std::uint64_t start = summary_start + summary.size();
    for (const auto& b : bodies) summary += framed(op, b);
    groups.push_back({op, {start, summary_start + summary.size() - start}});
  };
  group(kSchema, schemas_);
  group(kChannel, channels_);
  std::string st;
  le<std::uint64_t>(st, message_count_);
  le<std::uint16_t>(st, schemas_.size());
  le<std::uint32_t>(st, channels_.size()), le<std::uint32_t>(st, attachments_.size());
  le<std::uint32_t>(st, metadata_.size()), le<std::uint32_t>(st, chunks_.size());
  le<std::uint64_t>(st, start_ns_), le<std::uint64_t>(st, end_ns_);
  id_map(st, channel_counts_);
  group(kStatistics, {st});
  std::vector<std::string> bodies;
  for (const auto& c : chunks_) {
    std::string b;
    le<std::uint64_t>(b, c.start_ns), le<std::uint64_t>(b, c.end_ns), le<std::uint64_t>(b, c.offset),
        le<std::uint64_t>(b, c.length);
    id_map(b, c.index_offsets);
    le<std::uint64_t>(b, c.index_length);
    str(b, c.compression);
    le<std::uint64_t>(b, c.compressed_size), le<std::uint64_t>(b, c.uncompressed_size);
    bodies.push_back(std::move(b));
  }
  group(kChunkIndex, bodies);
  bodies.clear();
  for (const auto& a : attachments_) {
    std::string b;
    le<std::uint64_t>(b, a.offset), le<std::uint64_t>(b, a.length), le<std::uint64_t>(b, a.log_time_ns);
    le<std::uint64_t>(b, 0), le<std::uint64_t>(b, a.size);
    str(b, a.name), str(b, a.media_type);
    bodies.push_back(std::move(b));
  }
  group(kAttachmentIndex, bodies);
  bodies.clear();
  for (const auto& [at, m] : metadata_) {
    std::string b;
    le<std::uint64_t>(b, at), le<std::uint64_t>(b, m.first);
    str(b, m.second);
    bodies.push_back(std::move(b));
  }
  group(kMetadataIndex, bodies);
  const std::uint64_t offsets_start = summary_start + summary.size();
  for (const auto& [op, g] : groups) {
    std::string b;
    u8(b, op);
    le<std::uint64_t>(b, g.first), le<std::uint64_t>(b, g.second);
    summary += framed(kSummaryOffset, b);
  }
  // The footer's CRC covers the summary, the summary offsets and the footer up to the CRC itself.
  std::string footer;
  u8(footer, kFooter);
  le<std::uint64_t>(footer, 8 + 8 + 4);
  le<std::uint64_t>(footer, summary_start), le<std::uint64_t>(footer, offsets_start);
  le<std::uint32_t>(footer, crc32(footer, crc32(summary)));
  put(summary + footer);
  put(kMagic);
  std::FILE* f = f_;
  f_ = nullptr;
  if (std::fclose(f) != 0) {
    failed_ = true;
    throw McapError(path_.string() + ": cannot write: " + std::strerror(errno));
  }
}

}  // namespace hil::mcap
