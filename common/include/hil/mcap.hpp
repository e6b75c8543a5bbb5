// MCAP (https://mcap.dev/spec, major version 0), the container Foxglove, Lichtblick and
// PlotJuggler open: a small writer and a strict reader of our own (Debian packages no MCAP
// library; zstd is Debian's libzstd). The writer puts messages in chunks (zstd-compressed unless
// told otherwise), each with the CRC-32 of its records and followed by its message indexes, and
// ends the file with a summary (schemas, channels, statistics, chunk, attachment and metadata
// indexes, summary offsets) and a footer whose CRC covers it. A chunk is written whole and flushed
// to the OS, so a file whose writer was killed reads back up to its last whole chunk, and
// Writer::finish gives such a file its summary and footer. The reader streams records in bounded
// memory (one chunk at a time, uncompressed or zstd); anything malformed is an McapError naming
// the file and the byte offset of the record at fault; a file cut short (a crash) ends at its last
// whole record, which truncated() then says.
// Setup/offline code: allocates, does I/O and throws.
#pragma once

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "hil/csv_reader.hpp"

namespace hil::mcap {

// A CsvError so that whoever reads a table file (CSV or MCAP) catches one kind of error.
class McapError : public CsvError {
 public:
  using CsvError::CsvError;
};

using KeyValues = std::vector<std::pair<std::string, std::string>>;

// CRC-32 (ISO-HDLC, the one zlib and MCAP use) of data, continuing from crc (0 to start).
std::uint32_t crc32(std::string_view data, std::uint32_t crc = 0);

enum class Compression : std::uint8_t { none, zstd };

// What Writer::finish found and did.
struct Finished {
  bool was_whole = false;       // it had its footer and closing magic: nothing was done
  std::uint64_t bytes_cut = 0;  // the end of the file cut short by the crash, removed
  std::uint64_t chunks = 0, messages = 0;
  bool indexes_rebuilt = false;  // the last chunk's message indexes were cut, and are written anew
};

class Writer {
 public:
  // Creates `file` (truncating) and writes the magic and the header; throws McapError naming it.
  // A chunk is closed once it holds chunk_bytes (or by flush_chunk).
  Writer(const std::filesystem::path& file, std::string_view profile, std::size_t chunk_bytes = 1 << 20,
         Compression compression = Compression::zstd);
  ~Writer();  // closes the file as close() does when nothing was written wrong; never throws
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;

  // Written at once (outside chunks), and again in the summary. Ids count from 1.
  std::uint16_t add_schema(std::string_view name, std::string_view encoding, std::string_view data);
  std::uint16_t add_channel(std::uint16_t schema_id, std::string_view topic, std::string_view message_encoding,
                            const KeyValues& metadata = {});
  // Into the current chunk, with the channel's next sequence number; publish time = log time.
  void message(std::uint16_t channel_id, std::uint64_t log_time_ns, std::string_view data);
  // Writes the current chunk (if it holds anything) and its message indexes, and flushes the file.
  void flush_chunk();
  void metadata(std::string_view name, const KeyValues& values);  // a Metadata record (after the current chunk)
  void attachment(std::string_view name, std::string_view media_type, std::string_view data, std::uint64_t log_time_ns);
  // The last chunk, Data End, the summary, the footer and the closing magic; then the file is closed.
  void close();
  std::uint64_t messages() const { return message_count_; }

  // Finishes a file whose writer died (kill -9, power): the bytes after its last whole record are
  // removed, the message indexes of its last chunk written anew if they were cut, then what close()
  // writes (Data End, summary, footer, magic), after `before_close` (e.g. an attachment). A file
  // that already ends in a footer is left as it is (was_whole). Throws McapError naming the file
  // and the record at fault when the file is not one to finish (no MCAP magic or header, a damaged
  // chunk): such a file is left untouched, nothing whole is ever removed.
  static Finished finish(const std::filesystem::path& file, const std::function<void(Writer&)>& before_close = {});
  const std::filesystem::path& file() const { return path_; }

 private:
  struct ChunkIndex {
    std::uint64_t start_ns, end_ns, offset, length, index_length, compressed_size, uncompressed_size;
    std::string compression;
    std::map<std::uint16_t, std::uint64_t> index_offsets;
  };
  struct Resume {};
  Writer(Resume, const std::filesystem::path& file, std::FILE* f);                    // finish(): a file opened for update
  static std::string message_index(std::uint16_t channel, std::string_view entries);  // the record, framed
  void count_message(std::uint16_t channel_id, std::uint64_t log_time_ns);            // into the statistics
  struct ResumeWalk;
  void resume(std::uint8_t opcode, std::string_view body, std::uint64_t at, ResumeWalk& walk);  // finish(): one record
  struct AttachmentIndex {
    std::uint64_t offset, length, log_time_ns, size;
    std::string name, media_type;
  };
  void put(std::string_view bytes);                                  // to the file, counting the offset; throws naming the file
  std::uint64_t record(std::uint8_t opcode, std::string_view body);  // returns the record's offset

  std::filesystem::path path_;
  std::FILE* f_ = nullptr;
  std::uint64_t offset_ = 0;
  std::size_t chunk_bytes_;
  Compression compression_ = Compression::zstd;
  std::vector<std::string> schemas_, channels_;  // their records' bodies, for the summary
  std::vector<std::uint32_t> sequence_;          // per channel (index id - 1)
  std::map<std::uint16_t, std::uint64_t> channel_counts_;
  std::string chunk_;  // the records of the open chunk
  std::uint64_t chunk_start_ns_ = 0, chunk_end_ns_ = 0;
  std::map<std::uint16_t, std::string> chunk_index_;  // per channel: (log time, offset) pairs
  std::vector<ChunkIndex> chunks_;
  std::vector<AttachmentIndex> attachments_;
  std::vector<std::pair<std::uint64_t, std::pair<std::uint64_t, std::string>>> metadata_;  // offset, (length, name)
  std::uint64_t message_count_ = 0, start_ns_ = 0, end_ns_ = 0;
  bool failed_ = false;
};

struct Schema {
  std::uint16_t id = 0;
  std::string name, encoding, data;
};
struct Channel {
  std::uint16_t id = 0, schema_id = 0;
  std::string topic, message_encoding;
  KeyValues metadata;
};
struct Message {
  std::uint16_t channel_id = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time_ns = 0, publish_time_ns = 0;
  std::string_view data;     // valid until the next call of next()
  std::uint64_t offset = 0;  // of its record in the file; of its chunk's record when that chunk is compressed
};

// Streams the records of a file from its start: schemas and channels as they come, and messages
// (top-level or inside chunks) one at a time.
class Reader {
 public:
  explicit Reader(const std::filesystem::path& file);  // checks the magic and the header record
  ~Reader();
  Reader(const Reader&) = delete;
  Reader& operator=(const Reader&) = delete;

  // The next message; false after the Data End record, at the end of the file, or where the file
  // is cut short (truncated()).
  bool next(Message& m);
  const std::map<std::uint16_t, Schema>& schemas() const { return schemas_; }
  const std::map<std::uint16_t, Channel>& channels() const { return channels_; }
  const std::vector<std::pair<std::string, KeyValues>>& metadata() const { return metadata_; }          // seen so far
  const std::vector<std::pair<std::string, std::string>>& attachments() const { return attachments_; }  // name, data
  bool truncated() const { return truncated_; }
  std::uint64_t bytes_read() const { return offset_; }
  std::uint64_t file_bytes() const { return file_bytes_; }
  const std::filesystem::path& file() const { return path_; }

 private:
  [[noreturn]] void fail(std::uint64_t offset, const std::string& what) const;
  bool read_record(std::uint8_t& opcode, std::string& body, std::uint64_t& at);  // false at the end
  void take(std::uint8_t opcode, std::string_view body, std::uint64_t at);       // schema, channel, metadata...

  std::filesystem::path path_;
  std::FILE* f_ = nullptr;
  std::uint64_t offset_ = 0, file_bytes_ = 0;
  std::map<std::uint16_t, Schema> schemas_;
  std::map<std::uint16_t, Channel> channels_;
  std::vector<std::pair<std::string, KeyValues>> metadata_;
  std::vector<std::pair<std::string, std::string>> attachments_;
  std::string record_, chunk_;  // the last record; the records of the chunk being read
  std::size_t chunk_pos_ = 0;
  std::uint64_t chunk_at_ = 0, chunk_data_at_ = 0;  // file offsets of the chunk record and of its records
  bool in_chunk_ = false, chunk_compressed_ = false, done_ = false, truncated_ = false;
};

}  // namespace hil::mcap
