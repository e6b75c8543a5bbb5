// A run's events.jsonl read incrementally (GET /api/runs/{id}/events?offset=N): the console asks
// for what was appended since its last look instead of the whole file every second (a fast soak's
// page fetched 21 MB in 70 s that way and fell minutes behind). Loop statistics (overruns, limited
// commands) come folded into one summary per kind and second of run time, with the worst; every
// other event (operator actions, injections, interlocks, faults) comes whole, once, in file order.
#pragma once

#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

namespace hil::bench {

// The most bytes of the file one answer covers; a client follows next_offset for the rest.
inline constexpr std::uint64_t kEventFeedMaxBytes = 256 * 1024;

// {"offset", "next_offset", "size", "events": [...], "summaries": [{"kind", "t0_s", "count",
// "utc" (of the first), "worst_late_us" and "worst_t_s" (overruns)}], "unreadable": n}, read
// from `fd` (events.jsonl opened by open_inside, `size` bytes; `name` for errors). Only whole
// lines are read: a line being written is left for the next call. A line longer than max_bytes
// (no event is) is skipped whole: next_offset is the start of the line after it, and the answer
// counts it in "unreadable" and "too_long" with a "note" (a next_offset inside it was refused by
// the next call, and the feed stood still). Throws BadField("offset") for an offset past the end
// or not at the start of a line, std::runtime_error when the file cannot be read.
nlohmann::json event_feed(int fd, std::uint64_t size, const std::string& name, std::uint64_t offset,
                          std::uint64_t max_bytes = kEventFeedMaxBytes);

// Whether a kind is a loop statistic summarised per second rather than listed ("overrun",
// "cmd_limited").
bool summarised_event_kind(const std::string& kind);

}  // namespace hil::bench
