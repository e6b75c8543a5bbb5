#include <cerrno>
#include <cstring>

#include "hil/mcap.hpp"
#include "mcap_internal.hpp"

namespace hil::mcap {

using detail::Fields;
using detail::kMagic;

Reader::Reader(const std::filesystem::path& file) : path_(file) {
  f_ = std::fopen(file.c_str(), "rb");
  if (f_ == nullptr) throw McapError(file.string() + ": cannot open: " + std::strerror(errno));
  std::error_code ec;
  file_bytes_ = std::filesystem::file_size(file, ec);
  char magic[8];
  if (std::fread(magic, 1, 8, f_) != 8 || std::string_view(magic, 8) != kMagic) {
    std::fclose(f_), f_ = nullptr;
    throw McapError(file.string() + ": at byte 0: not an MCAP file (its first 8 bytes are not the MCAP magic, version 0)");
  }
  offset_ = 8;
  std::uint8_t op = 0;
  std::uint64_t at = 0;
  if (!read_record(op, record_, at) || op != 0x01) {
    std::fclose(f_), f_ = nullptr;
    throw McapError(file.string() + ": at byte 8: the MCAP header record must follow the magic");
  }
}

Reader::~Reader() {
  if (f_ != nullptr) std::fclose(f_);
}

void Reader::fail(std::uint64_t offset, const std::string& what) const {
  throw McapError(path_.string() + ": record at byte " + std::to_string(offset) + ": " + what);
}

// One top-level record; false at the end of the file or where it is cut short (truncated_).
bool Reader::read_record(std::uint8_t& opcode, std::string& body, std::uint64_t& at) {
  unsigned char head[9];
  at = offset_;
  const std::size_t got = std::fread(head, 1, 9, f_);
  if (got < 9) {
    truncated_ = got > 0;
    return false;
  }
  opcode = head[0];
  std::uint64_t n = 0;
  for (int i = 0; i < 8; ++i) n |= static_cast<std::uint64_t>(head[1 + i]) << (8 * i);
  // Past the file's end: a record cut short by a crash (the file ends inside it). Checked before
  // anything is allocated, so a hostile length costs nothing.
  if (n > file_bytes_ || at + 9 + n > file_bytes_) {
    truncated_ = true;
    return false;
  }
  body.resize(n);
  if (n > 0 && std::fread(body.data(), 1, n, f_) != n) {
    truncated_ = true;
    return false;
  }
  offset_ = at + 9 + n;
  return true;
}

void Reader::take(std::uint8_t opcode, std::string_view body, std::uint64_t at) {
  Fields r{body, 0, ""};
  switch (opcode) {
    case 0x03: {
      r.record = "schema";
      Schema s;
      std::string_view data;
      if (!r.num(s.id) || !r.str(s.name) || !r.str(s.encoding) || !r.str(data))
        fail(at, r.short_of("id, name, encoding or data"));
      s.data.assign(data);
      if (s.id == 0) return;  // "invalid and should be ignored by readers"
      schemas_[s.id] = std::move(s);
      return;
    }
    case 0x04: {
      r.record = "channel";
      Channel c;
      if (!r.num(c.id) || !r.num(c.schema_id) || !r.str(c.topic) || !r.str(c.message_encoding) || !r.kv(c.metadata))
        fail(at, r.short_of("id, schema_id, topic, message_encoding or metadata"));
      if (c.schema_id != 0 && schemas_.count(c.schema_id) == 0)
        fail(at, "channel " + std::to_string(c.id) + " ('" + c.topic.substr(0, 80) + "') names schema " +
                     std::to_string(c.schema_id) + ", which no earlier schema record defines");
      channels_[c.id] = std::move(c);
      return;
    }
    case 0x0C: {
      r.record = "metadata";
      std::string name;
      KeyValues kv;
      if (!r.str(name) || !r.kv(kv)) fail(at, r.short_of("name or metadata"));
      metadata_.emplace_back(std::move(name), std::move(kv));
      return;
    }
    case 0x09: {
      r.record = "attachment";
      std::uint64_t log_time = 0, create_time = 0, size = 0;
      std::string_view name, media, data;
      std::uint32_t crc = 0;
      if (!r.num(log_time) || !r.num(create_time) || !r.str(name) || !r.str(media) || !r.num(size) || !r.bytes(size, data))
        fail(at, r.short_of("log_time, create_time, name, media_type or data"));
      const std::size_t before_crc = r.pos;
      if (!r.num(crc)) fail(at, r.short_of("crc"));
      if (crc != 0 && crc != crc32(body.substr(0, before_crc)))
        fail(at, "attachment '" + std::string(name.substr(0, 80)) + "': its CRC-32 does not match its content");
      attachments_.emplace_back(std::string(name), std::string(data));
      return;
    }
    default: return;  // indexes, statistics and unknown opcodes carry no messages: skipped, as the spec asks
  }
}

bool Reader::next(Message& m) {
  for (;;) {
    if (in_chunk_) {
      if (chunk_pos_ >= chunk_.size()) {
        in_chunk_ = false;
        continue;
      }
      // A record of a compressed chunk has no byte in the file: the chunk's offset, and where in
      // its decompressed records.
      const std::uint64_t at = chunk_compressed_ ? chunk_at_ : chunk_data_at_ + chunk_pos_;
      const std::size_t pos = chunk_pos_;
      const auto inner = [&](const std::string& what) {
        return chunk_compressed_ ? "byte " + std::to_string(pos) + " of the chunk's decompressed records: " + what : what;
      };
      if (chunk_.size() - chunk_pos_ < 9) fail(at, inner("a record inside a chunk runs past the chunk's end"));
      const auto op = static_cast<std::uint8_t>(chunk_[chunk_pos_]);
      std::uint64_t n = 0;
      for (int i = 0; i < 8; ++i)
        n |= static_cast<std::uint64_t>(static_cast<std::uint8_t>(chunk_[chunk_pos_ + 1 + i])) << (8 * i);
      if (n > chunk_.size() - chunk_pos_ - 9) fail(at, inner("a record inside a chunk runs past the chunk's end"));
      const std::string_view body(chunk_.data() + chunk_pos_ + 9, n);
      chunk_pos_ += 9 + n;
      if (op == 0x05) {
        Fields r{body, 0, "message"};
        if (!r.num(m.channel_id) || !r.num(m.sequence) || !r.num(m.log_time_ns) || !r.num(m.publish_time_ns))
          fail(at, inner(r.short_of("channel_id, sequence, log_time or publish_time")));
        if (channels_.count(m.channel_id) == 0)
          fail(at, inner("a message on channel " + std::to_string(m.channel_id) + ", which no earlier channel record defines"));
        m.data = body.substr(r.pos), m.offset = at;
        return true;
      }
      if (op == 0x03 || op == 0x04) {
        take(op, body, at);
        continue;
      }
      fail(at, inner("opcode " + std::to_string(op) + " inside a chunk (only schema, channel and message records may be there)"));
    }
    if (done_ || f_ == nullptr) return false;
    std::uint8_t op = 0;
    std::uint64_t at = 0;
    if (!read_record(op, record_, at)) {
      done_ = true;
      return false;
    }
    if (op == 0x0F || op == 0x02) {  // Data End (or a footer without one): the messages are over
      done_ = true;
      return false;
    }
    if (op == 0x05) {
      Fields r{record_, 0, "message"};
      if (!r.num(m.channel_id) || !r.num(m.sequence) || !r.num(m.log_time_ns) || !r.num(m.publish_time_ns))
        fail(at, r.short_of("channel_id, sequence, log_time or publish_time"));
      if (channels_.count(m.channel_id) == 0)
        fail(at, "a message on channel " + std::to_string(m.channel_id) + ", which no earlier channel record defines");
      m.data = std::string_view(record_).substr(r.pos), m.offset = at;
      return true;
    }
    if (op == 0x06) {
      detail::ChunkFields c;
      if (std::string e = detail::parse_chunk(record_, c); !e.empty()) fail(at, e);
      if (std::string e = detail::chunk_records(c, chunk_); !e.empty()) fail(at, e);
      chunk_pos_ = 0, in_chunk_ = true;
      chunk_at_ = at;
      chunk_compressed_ = !c.compression.empty();
      chunk_data_at_ = at + 9 + static_cast<std::uint64_t>(c.records.data() - record_.data());
      continue;
    }
    take(op, record_, at);
  }
}

}  // namespace hil::mcap
