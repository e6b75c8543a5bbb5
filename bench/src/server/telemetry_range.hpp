// A time range of a recorded run's telemetry.csv at full resolution, for the report's zoom (a 10 s
// window of a one-hour 1 kHz run is 10 000 rows; the report embeds only a thinned overview). The
// rows are found by bisecting the file's byte offsets on t_s (the recorder writes t_s increasing,
// one row a line), so a request reads about log2(size) short pieces plus its own rows, whatever the
// run's length: no index to build or keep, and a file still being written is read up to its last
// whole line. Bounded: at most `max_rows` rows, else refused naming the range.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace hil::bench {

inline constexpr std::uint64_t kTelemetryRangeMaxRows = 50000;  // the most a request may ask for

struct TelemetryRange {
  double from_s = 0, to_s = 0;       // rows with from_s <= t_s <= to_s
  std::vector<std::string> columns;  // telemetry schema names (t_s is always given)
  std::uint64_t max_rows = 20000;
};

// The rows of `q` from the CSV open on `fd` (`size` bytes; read with pread, the offset is not
// moved) as JSON: {"from_s","to_s","rows","t_s":[...],"columns":{"name":[...]},"absent":[...]},
// a value that is no finite number null. A column of the schema the file does not have (the
// truth on a CAN rig) is listed in "absent". Throws BadField("columns") for a name that is not a
// telemetry column, BadField("to_s") when the range holds more than max_rows rows, and
// std::runtime_error naming `name` and the byte for a file that is not a telemetry.csv.
std::string telemetry_range_json(int fd, std::uint64_t size, const std::string& name, const TelemetryRange& q);

}  // namespace hil::bench
