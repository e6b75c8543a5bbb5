// What the runs' and the analyses' routes share of a run folder: whether a name is one, its
// files opened without following a link, and its record once the run has ended.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "api_impl.hpp"

namespace hil::bench::api {

// Whether runs_dir/id is a run folder: a plain name, a folder itself (not a link to one
// elsewhere), holding a run.json (of any kind: reading it says what is wrong with it).
bool is_run_dir(const std::filesystem::path& runs_dir, const std::string& id);

// Whether a folder entry is a regular file itself, not a link to one.
bool plain_file(const std::filesystem::directory_entry& e);

// A file below `base` (parts: plain names) opened through open_inside, the one way a run
// folder's files are opened: 404 `missing` (which names it) when it is not there, 403 naming the
// path (never its content) when it is a symbolic link, a FIFO, a device or no regular file. The
// descriptor is closed with the last copy of `fd`.
struct RunFile {
  std::shared_ptr<const int> fd;
  std::uint64_t size = 0;
  std::string name;  // "base/part/...", for errors
};
RunFile open_run_file(const std::filesystem::path& base, const std::vector<std::string>& parts, const std::string& missing);

// A file below `base` (parts: plain names), opened now without following a symbolic link at any
// part (open_inside): what is served is the file that was checked, never one a link points at
// outside the runs folder (an events.jsonl linked to /etc/passwd is refused). 404 `missing`
// when it is not there, 403 naming the path (never its content) when it is a link or no file.
Reply opened_file(const std::filesystem::path& base, const std::vector<std::string>& parts, const std::string& missing);

// An HTML file so opened, shown inline (parts empty: the header fields alone).
Reply html_file(const std::filesystem::path& base, const std::vector<std::string>& parts);

// 404 naming `id` unless it is a run folder.
void require_run(const ApiServer::Impl& api, const std::string& id);

// The folder of a recorded run (404 otherwise) and its record (422 when unreadable), 409 while it runs.
std::filesystem::path ended_run(const ApiServer::Impl& api, const std::string& id, RunRecord* record = nullptr);

// A run folder's record as the API shows it: its run.json, or, while that file still says
// "running" for a run this server ended, the end the runner keeps (CampaignRunner::unrecorded_end).
RunRecord record_of(const ApiServer::Impl& api, const std::filesystem::path& dir);

}  // namespace hil::bench::api
