// Chunk bodies: their fields, and zstd through Debian's libzstd.
#include <memory>

#include <zstd.h>

#include "mcap_internal.hpp"

namespace hil::mcap::detail {
namespace {

// One context per thread, reused chunk after chunk (ZSTD_compress would allocate one each time).
struct CCtxFree {
  void operator()(ZSTD_CCtx* c) const { ZSTD_freeCCtx(c); }
};
struct DCtxFree {
  void operator()(ZSTD_DCtx* d) const { ZSTD_freeDCtx(d); }
};

// Streams the frame(s) of `in` into out, never past `limit` bytes: a hostile size field or a
// frame that decompresses to more than the chunk says is an error, not an allocation.
std::string zstd_decompress(std::string_view in, std::uint64_t limit, std::string& out) {
  thread_local std::unique_ptr<ZSTD_DCtx, DCtxFree> dctx(ZSTD_createDCtx());
  if (!dctx) return "zstd: cannot create a decompression context";
  ZSTD_DCtx_reset(dctx.get(), ZSTD_reset_session_only);
  out.clear();
  ZSTD_inBuffer src{in.data(), in.size(), 0};
  constexpr std::size_t kStep = 64 * 1024;
  std::size_t ret = 1;
  while (src.pos < src.size || ret != 0) {
    const std::size_t have = out.size();
    if (have >= limit + 1) return "zstd: the records decompress to more than the chunk's uncompressed_size";
    out.resize(have + std::min<std::uint64_t>(kStep, limit + 1 - have));
    ZSTD_outBuffer dst{out.data() + have, out.size() - have, 0};
    ret = ZSTD_decompressStream(dctx.get(), &dst, &src);
    out.resize(have + dst.pos);
    if (ZSTD_isError(ret)) return std::string("zstd: ") + ZSTD_getErrorName(ret);
    if (dst.pos == 0 && src.pos == src.size && ret != 0) return "zstd: the compressed records end inside a frame";
  }
  if (out.size() > limit) return "zstd: the records decompress to more than the chunk's uncompressed_size";
  return "";
}

}  // namespace

std::string parse_chunk(std::string_view body, ChunkFields& c) {
  Fields r{body, 0, "chunk"};
  std::uint64_t records_size = 0;
  if (!r.num(c.start_ns) || !r.num(c.end_ns) || !r.num(c.uncompressed_size) || !r.num(c.crc) || !r.str(c.compression) ||
      !r.num(records_size) || !r.bytes(records_size, c.records))
    return r.short_of("message_start_time .. records");
  return "";
}

std::string chunk_records(const ChunkFields& c, std::string& out) {
  if (c.uncompressed_size > kMaxChunkRecordsBytes)
    return "chunk: uncompressed_size " + std::to_string(c.uncompressed_size) + " is beyond what this reader takes (" +
           std::to_string(kMaxChunkRecordsBytes >> 20) + " MiB)";
  if (c.compression.empty()) {
    out.assign(c.records);
  } else if (c.compression == "zstd") {
    if (std::string e = zstd_decompress(c.records, c.uncompressed_size, out); !e.empty()) return "chunk: " + e;
  } else {
    return "chunk compressed with '" + std::string(c.compression.substr(0, 40)) +
           "': this reader reads uncompressed and zstd chunks (hilbench writes zstd)";
  }
  if (c.uncompressed_size != out.size())
    return "chunk: uncompressed_size " + std::to_string(c.uncompressed_size) + " but its records hold " +
           std::to_string(out.size()) + " bytes";
  if (c.crc != 0 && c.crc != crc32(out)) return "chunk: its CRC-32 does not match its records (a damaged file)";
  return "";
}

void zstd_compress(std::string_view in, std::string& out, const std::string& file) {
  thread_local std::unique_ptr<ZSTD_CCtx, CCtxFree> cctx(ZSTD_createCCtx());
  if (!cctx) throw McapError(file + ": zstd: cannot create a compression context");
  const std::size_t at = out.size();
  out.resize(at + ZSTD_compressBound(in.size()));
  const std::size_t n = ZSTD_compressCCtx(cctx.get(), out.data() + at, out.size() - at, in.data(), in.size(), kZstdLevel);
  if (ZSTD_isError(n)) throw McapError(file + ": zstd: " + ZSTD_getErrorName(n));
  out.resize(at + n);
}

}  // namespace hil::mcap::detail
