// Writer::finish: the summary and footer of a file whose writer was killed. Its records are walked
// from the start (each chunk decompressed and its messages counted, as the summary's statistics
// and the rebuilt indexes need), the tail cut by the crash is removed, and close() does the rest.
#include <cerrno>
#include <cstring>

#include <unistd.h>

#include "hil/mcap.hpp"
#include "mcap_internal.hpp"

namespace hil::mcap {

using namespace detail;

namespace {

struct FileCloser {
  std::FILE* f;
  ~FileCloser() {
    if (f != nullptr) std::fclose(f);
  }
};

// Whether the file ends in a footer record and the closing magic (its CRC is the reader's business).
bool ends_whole(std::FILE* f, std::uint64_t size) {
  constexpr std::uint64_t kFooterRecord = 1 + 8 + 20;
  if (size < 8 + kFooterRecord + 8) return false;
  unsigned char tail[kFooterRecord + 8];
  if (std::fseek(f, static_cast<long>(size - sizeof tail), SEEK_SET) != 0 || std::fread(tail, 1, sizeof tail, f) != sizeof tail)
    return false;
  return tail[0] == kFooter && tail[1] == 20 && std::memcmp(tail + kFooterRecord, kMagic.data(), 8) == 0;
}

[[noreturn]] void fail_at(const std::string& file, std::uint64_t at, const std::string& what) {
  throw McapError(file + ": record at byte " + std::to_string(at) + ": " + what + "; the file is left as it is");
}

// The messages of a chunk's (uncompressed) records: (channel, log time, offset in the records).
template <class F>
void each_message(std::string_view records, const std::string& file, std::uint64_t at, F&& on_message) {
  for (std::size_t p = 0; p < records.size();) {
    Fields r{records.substr(p), 0, "a record in the chunk"};
    std::uint8_t op = 0;
    std::uint64_t n = 0;
    std::uint16_t channel = 0;
    std::uint32_t seq = 0;
    std::uint64_t t = 0;
    if (!r.num(op) || !r.num(n) || n > records.size() - p - 9) fail_at(file, at, "a record inside the chunk runs past its end");
    if (op == kMessage) {
      if (!r.num(channel) || !r.num(seq) || !r.num(t)) fail_at(file, at, "a message inside the chunk ends early");
      on_message(channel, t, p);
    }
    p += 9 + n;
  }
}

}  // namespace

struct Writer::ResumeWalk {
  std::string file, records;
  std::map<std::uint16_t, std::string> entries;  // the last chunk's (log time, offset) pairs per channel
  bool header = false, last_chunk_open = false;
};

Writer::Writer(Resume, const std::filesystem::path& file, std::FILE* f) : path_(file), f_(f), chunk_bytes_(1 << 20) {}

void Writer::count_message(std::uint16_t channel_id, std::uint64_t log_time_ns) {
  if (message_count_ == 0 || log_time_ns < start_ns_) start_ns_ = log_time_ns;
  if (message_count_ == 0 || log_time_ns > end_ns_) end_ns_ = log_time_ns;
  ++message_count_, ++channel_counts_[channel_id];
}

// One whole record of the file being finished, taken as the writer would have kept it.
void Writer::resume(std::uint8_t op, std::string_view body, std::uint64_t at, ResumeWalk& walk) {
  const std::uint64_t length = 9 + body.size();
  if (op != kMessageIndex) walk.last_chunk_open = false;
  if (op == kHeader) walk.header = true;
  if (op == kSchema) schemas_.emplace_back(body);
  if (op == kChannel) channels_.emplace_back(body), sequence_.push_back(0);
  if (op == kMessage) {
    Fields r{body, 0, "message"};
    std::uint16_t channel = 0;
    std::uint32_t seq = 0;
    std::uint64_t t = 0;
    if (!r.num(channel) || !r.num(seq) || !r.num(t)) fail_at(walk.file, at, r.short_of("channel_id, sequence or log_time"));
    count_message(channel, t);
  }
  if (op == kChunk) {
    ChunkFields c;
    if (std::string e = parse_chunk(body, c); !e.empty()) fail_at(walk.file, at, e);
    if (std::string e = chunk_records(c, walk.records); !e.empty()) fail_at(walk.file, at, e);
    walk.entries.clear();
    each_message(walk.records, walk.file, at, [&](std::uint16_t channel, std::uint64_t t, std::uint64_t offset) {
      le<std::uint64_t>(walk.entries[channel], t), le<std::uint64_t>(walk.entries[channel], offset);
      count_message(channel, t);
    });
    chunks_.push_back(
        {c.start_ns, c.end_ns, at, length, 0, c.records.size(), c.uncompressed_size, std::string(c.compression), {}});
    walk.last_chunk_open = true;
  }
  if (op == kMessageIndex && walk.last_chunk_open) {
    std::uint16_t channel = 0;
    Fields r{body, 0, "message index"};
    if (r.num(channel)) chunks_.back().index_offsets[channel] = at, chunks_.back().index_length += length;
  }
  if (op == kMetadata) {
    Fields r{body, 0, "metadata"};
    std::string name;
    if (!r.str(name)) fail_at(walk.file, at, r.short_of("name"));
    metadata_.push_back({at, {length, name}});
  }
  if (op == kAttachment) {
    Fields r{body, 0, "attachment"};
    std::uint64_t log_time = 0, create_time = 0, data_size = 0;
    std::string name, media;
    if (!r.num(log_time) || !r.num(create_time) || !r.str(name) || !r.str(media) || !r.num(data_size))
      fail_at(walk.file, at, r.short_of("log_time, create_time, name, media_type or data"));
    attachments_.push_back({at, length, log_time, data_size, name, media});
  }
}

Finished Writer::finish(const std::filesystem::path& file, const std::function<void(Writer&)>& before_close) {
  const std::string name = file.string();
  FileCloser fc{std::fopen(file.c_str(), "r+b")};
  std::FILE* f = fc.f;
  if (f == nullptr) throw McapError(name + ": cannot open for update: " + std::strerror(errno));
  std::error_code ec;
  const std::uint64_t size = std::filesystem::file_size(file, ec);
  char magic[8];
  if (ec || std::fread(magic, 1, 8, f) != 8 || std::string_view(magic, 8) != kMagic)
    throw McapError(name + ": at byte 0: not an MCAP file (no MCAP magic): nothing to finish");
  Finished done;
  if (ends_whole(f, size)) {
    done.was_whole = true;
    return done;
  }
  Writer w(Resume{}, file, nullptr);  // f_ stays null until the walk is done: a throw closes nothing
  ResumeWalk walk{name, {}, {}, false, false};
  std::uint64_t at = 8;
  std::string body;
  std::fseek(f, 8, SEEK_SET);
  for (;;) {
    unsigned char head[9];
    if (size - at < 9 || std::fread(head, 1, 9, f) != 9) break;
    std::uint64_t n = 0;
    for (int i = 0; i < 8; ++i) n |= static_cast<std::uint64_t>(head[1 + i]) << (8 * i);
    if (n > size - at - 9) break;  // cut short by the crash
    body.resize(n);
    if (n > 0 && std::fread(body.data(), 1, n, f) != n) break;
    const std::uint8_t op = head[0];
    if (!walk.header && op != kHeader) fail_at(name, at, "the MCAP header record must follow the magic");
    // Data End, a footer or summary records: a close() cut short; its summary is written anew.
    if (op == kDataEnd || op == kFooter || (op >= kChunkIndex && op != kAttachment && op != kMetadata)) break;
    w.resume(op, body, at, walk);
    at += 9 + n;
  }
  if (!walk.header) fail_at(name, 8, "no whole MCAP header record: nothing to finish");
  std::uint64_t cut = at;
  // The last chunk's indexes: whole, or written anew after the chunk (one per channel in it).
  if (!w.chunks_.empty() && w.chunks_.back().index_offsets.size() != walk.entries.size()) {
    cut = w.chunks_.back().offset + w.chunks_.back().length;
    done.indexes_rebuilt = true;
  }
  done.bytes_cut = size - cut;
  if (::ftruncate(fileno(f), static_cast<off_t>(cut)) != 0 || std::fseek(f, static_cast<long>(cut), SEEK_SET) != 0)
    throw McapError(name + ": cannot cut the file at byte " + std::to_string(cut) + ": " + std::strerror(errno));
  w.f_ = f, fc.f = nullptr;  // the writer closes it from here
  w.offset_ = cut;
  if (done.indexes_rebuilt) {
    ChunkIndex& last = w.chunks_.back();
    last.index_offsets.clear();
    std::string out;
    for (const auto& [channel, e] : walk.entries) {
      last.index_offsets[channel] = cut + out.size();
      out += message_index(channel, e);
    }
    last.index_length = out.size();
    w.put(out);
  }
  if (before_close) before_close(w);
  w.close();
  done.chunks = w.chunks_.size(), done.messages = w.message_count_;
  return done;
}

}  // namespace hil::mcap
