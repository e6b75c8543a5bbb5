// Fuzz target "measurement": the bytes as a measurement file (physics.md section 4), read by
//   1. hil::analysis::load_measurement (whole file, SI conversion, the kMinRows check);
//   2. hil::analysis::MeasurementReader in small chunks (the streaming path compare uses);
//   3. the common CSV reader directly, with a request of required, optional and increasing columns.
// Clear errors: hil::CsvError (file:line:column: what).
#include <cstddef>
#include <cstdint>

#include "fuzz_support.hpp"
#include "hil/analysis/measurement.hpp"
#include "hil/csv_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static hil::fuzz::InputFile file("measurement.csv");
  const auto& path = file.write(data, size);

  hil::fuzz::expect_clear_errors<hil::CsvError>("analysis::load_measurement", [&] {
    const auto m = hil::analysis::load_measurement(path);
    (void)m.rows.size();
  });
  hil::fuzz::expect_clear_errors<hil::CsvError>("analysis::MeasurementReader", [&] {
    hil::analysis::MeasurementReader reader(path);
    hil::analysis::MeasurementRows rows;
    while (reader.next(rows, 7)) (void)reader.progress();
    (void)hil::analysis::header_line(path);
  });
  hil::fuzz::expect_clear_errors<hil::CsvError>("hil::read_csv", [&] {
    hil::CsvRequest request{{"t_s", "a"}, {"b", "t_s2"}, "t_s"};
    hil::CsvHeader header;
    const auto chunk = hil::read_csv(path, request, &header);
    (void)chunk.rows();
  });
  return 0;
}
