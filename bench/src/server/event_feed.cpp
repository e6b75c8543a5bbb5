#include "event_feed.hpp"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <stdexcept>
#include <string>
#include <utility>

#include "hil/bench/campaign/run_marks.hpp"
#include "hil/bench/server/runner.hpp"

namespace hil::bench {

using nlohmann::json;

bool summarised_event_kind(const std::string& kind) { return kind == "overrun" || kind == "cmd_limited"; }

json event_feed(const std::filesystem::path& events_file, std::uint64_t offset, std::uint64_t max_bytes) {
  std::ifstream in(events_file, std::ios::binary);
  if (!in) throw std::runtime_error(events_file.string() + ": cannot open (" + std::strerror(errno) + ")");
  in.seekg(0, std::ios::end);
  const auto size = static_cast<std::uint64_t>(in.tellg());
  if (offset > size) {
    throw BadField("offset", "'offset' " + std::to_string(offset) + " is past the end of events.jsonl (" + std::to_string(size) +
                                 " bytes); start again from 0");
  }
  if (offset > 0) {  // a line's start follows a newline: any other offset would cut a line in two
    in.seekg(static_cast<std::streamoff>(offset - 1));
    if (in.get() != '\n') {
      throw BadField("offset", "'offset' " + std::to_string(offset) +
                                   " is not the start of a line of events.jsonl; use a next_offset this endpoint gave");
    }
  }
  const std::uint64_t want = std::min<std::uint64_t>(size - offset, max_bytes);
  std::string chunk(want, '\0');
  in.seekg(static_cast<std::streamoff>(offset));
  in.read(chunk.data(), static_cast<std::streamsize>(want));
  chunk.resize(static_cast<std::size_t>(in.gcount()));

  // Whole lines only. A line longer than a whole chunk (no event is) is skipped as unreadable so
  // that the feed still moves on.
  std::size_t end = chunk.rfind('\n');
  std::uint64_t unreadable = 0;
  std::uint64_t next = offset;
  if (end == std::string::npos) {
    if (chunk.size() == max_bytes) next = offset + chunk.size(), ++unreadable;
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
  return {{"offset", offset}, {"next_offset", next},    {"size", size},
          {"events", events}, {"summaries", summaries}, {"unreadable", unreadable}};
}

}  // namespace hil::bench
