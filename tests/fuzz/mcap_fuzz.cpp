// Fuzz target "mcap": the bytes as a run's telemetry.mcap, read by
//   1. hil::mcap::Reader over every message, with the schemas, channels, metadata and attachments
//      it collects on the way (records, chunks and their CRCs, maps, strings);
//   2. hil::TableReader on the telemetry topic with a request of required, optional and increasing
//      columns (the JSON messages as rows);
//   3. hil::analysis::load_measurement (compare's and diagnose's reader of a run's MCAP);
//   4. hil::mcap::Writer::finish on a copy (what the server's interrupted-run scan does to a run
//      folder's file): a file it finishes (one not ending in a footer already) reads back whole
//      (no error, not truncated) whenever the input itself read without error. Chunks may be uncompressed or zstd (seed zstd_chunks).
// Clear errors: hil::CsvError (McapError is one): the file and the record's byte offset.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <stdexcept>

#include "fuzz_support.hpp"
#include "hil/analysis/measurement.hpp"
#include "hil/mcap.hpp"
#include "hil/table_reader.hpp"
#include "hil/telemetry_schema.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static hil::fuzz::InputFile file("telemetry.mcap");
  static hil::fuzz::InputFile copy("finished.mcap");
  const auto& path = file.write(data, size);

  bool read_whole = false;
  hil::fuzz::expect_clear_errors<hil::CsvError>("mcap::Reader", [&] {
    hil::mcap::Reader reader(path);
    hil::mcap::Message m;
    std::size_t bytes = 0;
    while (reader.next(m)) bytes += m.data.size() + reader.channels().at(m.channel_id).topic.size();
    for (const auto& [name, values] : reader.metadata()) bytes += name.size() + values.size();
    for (const auto& [name, blob] : reader.attachments()) bytes += name.size() + blob.size();
    (void)bytes, (void)reader.truncated();
    read_whole = true;
  });
  hil::fuzz::expect_clear_errors<hil::CsvError>("TableReader(mcap)", [&] {
    hil::TableReader reader(path, {{"t_s", "p_meas_mpa"}, {"gap_est_deg"}, "t_s"}, hil::telemetry::kTopic);
    hil::CsvChunk chunk;
    while (reader.next(chunk, 5)) (void)reader.where(chunk.lines.front(), "t_s");
  });
  hil::fuzz::expect_clear_errors<hil::CsvError>("analysis::load_measurement(mcap)", [&] {
    const auto m = hil::analysis::load_measurement(path);
    (void)m.rows.size();
  });
  const auto& finished = copy.write(data, size);
  bool done = false;
  hil::fuzz::expect_clear_errors<hil::CsvError>("mcap::Writer::finish", [&] {
    done = !hil::mcap::Writer::finish(finished).was_whole;  // a file ending in a footer is left as it is
  });
  if (done && read_whole) {
    try {
      hil::mcap::Reader reader(finished);
      hil::mcap::Message m;
      while (reader.next(m)) {}
      if (reader.truncated()) throw std::runtime_error("the finished file reads as cut short");
    } catch (const std::exception& e) {
      std::fprintf(stderr, "\nFINDING in mcap::Writer::finish: the finished file does not read back: %s\n", e.what());
      std::abort();
    }
  }
  return 0;
}
