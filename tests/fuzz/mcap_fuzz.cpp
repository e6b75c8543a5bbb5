// Fuzz target "mcap": the bytes as a run's telemetry.mcap, read by
//   1. hil::mcap::Reader over every message, with the schemas, channels, metadata and attachments
//      it collects on the way (records, chunks and their CRCs, maps, strings);
//   2. hil::TableReader on the telemetry topic with a request of required, optional and increasing
//      columns (the JSON messages as rows);
//   3. hil::analysis::load_measurement (compare's and diagnose's reader of a run's MCAP).
// Clear errors: hil::CsvError (McapError is one): the file and the record's byte offset.
#include <cstddef>
#include <cstdint>

#include "fuzz_support.hpp"
#include "hil/analysis/measurement.hpp"
#include "hil/mcap.hpp"
#include "hil/table_reader.hpp"
#include "hil/telemetry_schema.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static hil::fuzz::InputFile file("telemetry.mcap");
  const auto& path = file.write(data, size);

  hil::fuzz::expect_clear_errors<hil::CsvError>("mcap::Reader", [&] {
    hil::mcap::Reader reader(path);
    hil::mcap::Message m;
    std::size_t bytes = 0;
    while (reader.next(m)) bytes += m.data.size() + reader.channels().at(m.channel_id).topic.size();
    for (const auto& [name, values] : reader.metadata()) bytes += name.size() + values.size();
    for (const auto& [name, blob] : reader.attachments()) bytes += name.size() + blob.size();
    (void)bytes, (void)reader.truncated();
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
  return 0;
}
