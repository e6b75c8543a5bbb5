#include "api_run_files.hpp"

#include <unistd.h>

#include "hil/config.hpp"
#include "request_guard.hpp"

namespace hil::bench::api {

bool is_run_dir(const std::filesystem::path& runs_dir, const std::string& id) {
  if (!cfg::plain_name(id)) return false;
  std::error_code ec;
  return std::filesystem::symlink_status(runs_dir / id, ec).type() == std::filesystem::file_type::directory &&
         std::filesystem::symlink_status(runs_dir / id / "run.json", ec).type() != std::filesystem::file_type::not_found;
}

// Whether a folder entry is a regular file itself, not a link to one.
bool plain_file(const std::filesystem::directory_entry& e) {
  std::error_code ec;
  return e.symlink_status(ec).type() == std::filesystem::file_type::regular;
}

// A file below `base` (parts: plain names), opened now without following a symbolic link at any
// part (open_inside): what is served is the file that was checked, never one a link points at
// outside the runs folder (an events.jsonl linked to /etc/passwd is refused). 404 `missing`
// when it is not there, 403 naming the path (never its content) when it is a link or no file.
Reply opened_file(const std::filesystem::path& base, const std::vector<std::string>& parts, const std::string& missing) {
  std::filesystem::path path = base;
  for (const auto& p : parts) path /= p;
  bool absent = false;
  OpenedFile f;
  try {
    f = open_inside(base, parts, &absent);
  } catch (const std::exception& e) {
    throw ApiError{http::status::forbidden, "file not served", e.what()};
  }
  if (absent) throw ApiError{http::status::not_found, "unknown file", missing};
  Reply r;
  r.file = path;
  r.fd = std::shared_ptr<const int>(new int(f.fd), [](const int* fd) {
    if (*fd >= 0) ::close(*fd);
    delete fd;
  });
  return r;
}

Reply html_file(const std::filesystem::path& base, const std::vector<std::string>& parts) {
  Reply r = parts.empty() ? Reply{} : opened_file(base, parts, "no file " + parts.back());
  r.content_type = "text/html; charset=utf-8";
  r.extra_header = "inline";
  return r;
}

void require_run(const ApiServer::Impl& api, const std::string& id) {
  if (!is_run_dir(api.options.runs_dir, id)) {
    throw ApiError{http::status::not_found, "unknown run", "'" + id + "' is not a run (GET /api/runs lists them)"};
  }
}

std::filesystem::path ended_run(const ApiServer::Impl& api, const std::string& id, RunRecord* record) {
  const auto dir = api.options.runs_dir / id;
  if (!is_run_dir(api.options.runs_dir, id)) {
    throw ApiError{http::status::not_found, "unknown run", "'" + id + "' is not a run (GET /api/runs lists them)"};
  }
  RunRecord r;
  try {
    r = read_run_record_inside(dir);
  } catch (const std::exception& e) {
    throw ApiError{http::status::unprocessable_entity, "unreadable run.json", e.what()};
  }
  const auto end = r.outcome == Outcome::running ? api.runner.unrecorded_end(id) : std::nullopt;
  if (end && end->written) r = end->record;
  if (end && !end->written) {
    throw ApiError{http::status::conflict, "the run's record is not on disk",
                   "run '" + id +
                       "' has ended, but its final run.json could not be written, and a review reads that file; "
                       "free room in the runs folder and ask again (GET /api/runs/" +
                       id + " shows the end)"};
  }
  if (r.outcome == Outcome::running) {
    throw ApiError{http::status::conflict, "the run is still running",
                   "run '" + id + "' is reviewed once it has ended; abort or stop it, or wait"};
  }
  if (record != nullptr) *record = std::move(r);
  return dir;
}

RunRecord record_of(const ApiServer::Impl& api, const std::filesystem::path& dir) {
  RunRecord r = read_run_record_inside(dir);
  if (r.outcome == Outcome::running) {
    if (auto end = api.runner.unrecorded_end(dir.filename().string())) return std::move(end->record);
  }
  return r;
}

}  // namespace hil::bench::api
