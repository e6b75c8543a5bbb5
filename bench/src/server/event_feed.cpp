#include "event_feed.hpp"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <optional>
#include <map>
#include <stdexcept>
#include <string>
#include <utility>

#include "hil/bench/campaign/run_marks.hpp"
#include "hil/bench/server/runner.hpp"
#include "request_guard.hpp"

namespace hil::bench {

using nlohmann::json;

bool summarised_event_kind(const std::string& kind) { return kind == "overrun" || kind == "cmd_limited"; }

namespace {

// Where the line that starts before `from` ends: the byte after its newline, or nullopt while it
// has none yet (being written). Read in chunks: the scan holds no more than one in memory.
std::optional<std::uint64_t> end_of_line(int fd, std::uint64_t from, std::uint64_t size, const std::string& name) {
  constexpr std::size_t kChunk = 64 * 1024;
  for (std::uint64_t at = from; at < size; at += kChunk) {
    const std::string chunk = read_at(fd, at, kChunk, name);
    if (const auto nl = chunk.find('\n'); nl != std::string::npos) return at + nl + 1;
    if (chunk.size() < kChunk) break;
  }
  return std::nullopt;
}

}  // namespace

json event_feed(int fd, std::uint64_t size, const std::string& name, std::uint64_t offset, std::uint64_t max_bytes) {
  if (offset > size) {
    throw BadField("offset", "'offset' " + std::to_string(offset) + " is past the end of events.jsonl (" + std::to_string(size) +
                                 " bytes); start again from 0");
  }
  // A line's start follows a newline: any other offset would cut a line in two.
  if (offset > 0 && read_at(fd, offset - 1, 1, name) != "\n") {
    throw BadField("offset", "'offset' " + std::to_string(offset) +
                                 " is not the start of a line of events.jsonl; use a next_offset this endpoint gave");
  }
  std::string chunk = read_at(fd, offset, static_cast<std::size_t>(std::min<std::uint64_t>(size - offset, max_bytes)), name);

  // Whole lines only. A line longer than a whole chunk (no event is) is skipped to its end, so
  // that the feed moves on from the start of the next line.
  std::size_t end = chunk.rfind('\n');
  std::uint64_t unreadable = 0, too_long = 0;
  std::uint64_t next = offset;
  if (end == std::string::npos) {
    if (chunk.size() == max_bytes) {
      if (const auto after = end_of_line(fd, offset + chunk.size(), size, name)) next = *after, ++unreadable, ++too_long;
    }
    chunk.clear();
  } else {
    chunk.resize(end + 1);
    next = offset + chunk.size();
  }

  json events = json::array();
  // Summaries keyed by kind and whole second of run time, in the order first seen.
  std::map<std::pair<std::string, long long>, std::size_t> summary_index;
  json summaries = json::array();
  std::size_t pos = 0;
  while (pos < chunk.size()) {
    const std::size_t nl = chunk.find('\n', pos);
    const std::string_view line(chunk.data() + pos, nl - pos);
    pos = nl + 1;
    if (line.find_first_not_of(" \t\r") == std::string_view::npos) continue;
    json e = json::parse(line, nullptr, /*allow_exceptions=*/false);
    if (!e.is_object() || !e.contains("kind") || !e["kind"].is_string()) {
      ++unreadable;  // a torn line of a crash; the rest of the file still counts
      continue;
    }
    const std::string kind = e["kind"].get<std::string>();
    const double t_s = e.contains("t_s") && e["t_s"].is_number() ? e["t_s"].get<double>() : NAN;
    if (!summarised_event_kind(kind) || !std::isfinite(t_s)) {
      // The label the plots mark it with, worded as the reports do (run_marks.hpp).
      if (std::string mark = mark_label(e); !mark.empty() && std::isfinite(t_s)) e["mark"] = std::move(mark);
      events.push_back(std::move(e));
      continue;
    }
    const long long second = static_cast<long long>(std::floor(t_s));
    const auto [it, added] = summary_index.emplace(std::make_pair(kind, second), summaries.size());
    if (added) {
      summaries.push_back(
          {{"kind", kind}, {"t0_s", second}, {"count", 0}, {"utc", e.contains("utc") ? e["utc"] : json(nullptr)}});
    }
    json& s = summaries[it->second];
    s["count"] = s["count"].get<std::uint64_t>() + 1;
    if (kind == "overrun" && e.contains("late_us") && e["late_us"].is_number()) {
      const double late = e["late_us"].get<double>();
      if (!s.contains("worst_late_us") || late > s["worst_late_us"].get<double>()) {
        s["worst_late_us"] = late;
        s["worst_t_s"] = t_s;
      }
    }
  }
  json answer = {{"offset", offset}, {"next_offset", next},    {"size", size},
                 {"events", events}, {"summaries", summaries}, {"unreadable", unreadable}};
  if (too_long > 0) {
    answer["too_long"] = too_long;
    answer["note"] = "a line of more than " + std::to_string(max_bytes) + " bytes (at byte " + std::to_string(offset) +
                     ") is no event this feed reads: skipped; next_offset is the line after it";
  }
  return answer;
}

}  // namespace hil::bench
