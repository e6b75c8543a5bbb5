// The recorded runs: their list, a run's record and files, its events read by offset, and its
// report (made once on the job worker and kept in its folder).
#include <algorithm>
#include <cmath>

#include "analyses.hpp"
#include "api_router.hpp"
#include "api_run_files.hpp"
#include "event_feed.hpp"
#include "hil/bench/campaign/run_report.hpp"
#include "hil/config.hpp"
#include "hil/text_file.hpp"

namespace hil::bench::api {
namespace {

const FieldSpecs kEventsQuery = {
    {"offset", FieldType::whole, "bytes", 0, 9.0e15, false, "the byte of events.jsonl to read from (0 when not given)"}};
const FieldSpecs kReportQuery = {{"wait", FieldType::text, "", -INFINITY, INFINITY, false, "0: answer 202 at once; 1: wait"}};

Reply runs(const ApiServer::Impl& api) {
  json list = json::array();
  std::vector<std::filesystem::path> dirs;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(api.options.runs_dir, ec)) {
    if (is_run_dir(api.options.runs_dir, e.path().filename().string())) dirs.push_back(e.path());
  }
  std::sort(dirs.rbegin(), dirs.rend());  // newest first: names start with the UTC time
  for (const auto& d : dirs) {
    json j = {{"id", d.filename().string()}};
    try {
      const json r = record_of(api, d).to_json();
      for (const char* k : {"campaign", "run", "outcome", "reason", "start_utc", "stop_utc"}) j[k] = r[k];
      // The plant the run ran on (its recorded snapshot's file): the model its analyses default to.
      if (r.contains("config") && r["config"].is_object() && r["config"].value("plant_file", "") != "")
        j["plant"] = std::filesystem::path(r["config"].value("plant_file", "")).stem().string();
    } catch (const std::exception& e) {
      j["error"] = e.what();  // names the file, and the line and column
    }
    list.push_back(j);
  }
  return json_reply(http::status::ok, {{"runs", list}});
}

Reply run(const ApiServer::Impl& api, const std::string& id) {
  const auto dir = api.options.runs_dir / id;
  require_run(api, id);
  json files = json::array();
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    std::error_code size_ec;
    const auto bytes = e.file_size(size_ec);
    if (plain_file(e) && !size_ec && cfg::plain_name(e.path().filename().string()) && e.path().extension() != ".tmp") {
      files.push_back({{"name", e.path().filename().string()}, {"bytes", bytes}});
    }
  }
  json r;
  try {
    r = read_json_inside(api.options.runs_dir, {id, "run.json"});
  } catch (const std::exception& e) {
    throw ApiError{http::status::unprocessable_entity, "unreadable run.json", e.what()};
  }
  if (r.is_object() && r.value("outcome", json()) == "running") {
    if (const auto end = api.runner.unrecorded_end(id)) r = end->record.to_json();
  }
  return json_reply(http::status::ok, {{"id", id}, {"files", files}, {"run", r}});
}

Reply run_events(const Call& c) {
  const ApiServer::Impl& api = c.api;
  const std::string& id = c.args[0];
  require_run(api, id);
  const double offset = query_number(c.target, spec_of(c.route.query, "offset"), 0);
  try {
    const RunFile f = open_run_file(api.options.runs_dir, {id, "events.jsonl"}, "run '" + id + "' has no events.jsonl");
    return json_reply(http::status::ok, event_feed(*f.fd, f.size, f.name, static_cast<std::uint64_t>(offset)));
  } catch (const BadField& e) {
    throw ApiError{http::status::bad_request, "bad field", e.what(), e.field};
  }
}

Reply run_file(const ApiServer::Impl& api, const std::string& id, const std::string& file) {
  const auto path = api.options.runs_dir / id / file;
  // A .tmp is an output being made (report.html.tmp): half of one is never served, as the run's
  // file list (run()) never shows one.
  if (!is_run_dir(api.options.runs_dir, id) || !cfg::plain_name(file) || path.extension() == ".tmp") {
    throw ApiError{http::status::not_found, "unknown file", "run '" + id + "' has no file '" + file + "'"};
  }
  Reply r = opened_file(api.options.runs_dir, {id, file}, "run '" + id + "' has no file '" + file + "'");
  const auto ext = path.extension().string();
  r.content_type = ext == ".csv"     ? "text/csv"
                   : ext == ".json"  ? "application/json"
                   : ext == ".jsonl" ? "application/x-ndjson"
                                     : "application/octet-stream";
  r.extra_header = "attachment; filename=\"" + file + "\"";
  return r;
}

Reply run_report(const Call& c) {
  ApiServer::Impl& api = c.api;
  const std::string& id = c.args[0];
  const Target& t = c.target;
  const bool head = c.req.method() == http::verb::head;
  // ?wait= is 0 or 1: any other value (wait=false, wait=no) waited, the opposite of what it says.
  const auto wait = t.query.find("wait");
  if (wait != t.query.end() && wait->second != "0" && wait->second != "1") {
    throw ApiError{http::status::bad_request, "bad field",
                   "'wait' must be 0 (answer 202 at once) or 1 (wait for the report), got '" + printable(wait->second, 40) + "'",
                   "wait"};
  }
  const auto dir = ended_run(api, id);
  try {
    refuse_linked_run_files(dir);
  } catch (const std::exception& e) {
    throw ApiError{http::status::unprocessable_entity, "file not read", e.what()};
  }
  // Made once per run, on the job worker, and kept in its folder (analyses.hpp run_report_current).
  if (run_report_current(dir)) return html_file(api.options.runs_dir, {id, "report.html"});
  if (head) {
    // HEAD asks for the header fields, not for the report: making one (seconds for an hour's run,
    // a place in the job queue, a file written) only to drop its body is work nobody asked for.
    // Its length is not known before it is made, and HEAD may leave Content-Length out (RFC 9110
    // 9.3.2); a wrong one (0) would tell the client the report is empty. ?wait=0 changes nothing:
    // no job is queued, so there is none to answer with.
    Reply r = html_file({}, {});
    r.length_unknown = true;
    return r;
  }
  std::optional<JobStatus> job = api.jobs.find(id, "report");
  if (job && (job->state == JobState::done || job->state == JobState::failed)) {
    api.jobs.forget(id, "report");  // a failure is answered once; the next request tries again
    if (job->state == JobState::failed) throw ApiError{http::status::unprocessable_entity, "cannot make the report", job->error};
    job.reset();
  }
  if (!job) {
    JobStatus s;
    s.run = id;
    s.id = "report";
    s.kind = "report";
    try {
      // Stops between chunks of rows when the server stops (an hour's run takes seconds to read).
      job = api.jobs.submit(s, [dir](const JobQueue::Progress& progress, const std::atomic<bool>& cancel) {
        return make_run_report(dir, progress, &cancel);
      });
    } catch (const JobRefused& e) {
      throw ApiError{http::status::service_unavailable, "cannot queue the job", e.what()};
    }
  }
  Reply reply = json_reply(http::status::accepted, {{"report", job->to_json()}});
  if (wait != t.query.end() && wait->second == "0") return reply;
  auto w = std::make_shared<JobWait>();
  w->run = id;
  w->id = "report";
  w->then = [&api, dir, id](const JobStatus& s) -> Reply {
    if (s.state == JobState::done && std::filesystem::exists(dir / "report.html"))
      return html_file(api.options.runs_dir, {id, "report.html"});
    api.jobs.forget(id, "report");
    return error_reply(http::status::unprocessable_entity, "cannot make the report", s.error);
  };
  reply.wait = std::move(w);
  return reply;
}

}  // namespace

std::vector<Route> run_routes() {
  return {
      {130,
       http::verb::get,
       "/api/runs",
       "the recorded runs, newest first",
       [](const Call& c) { return runs(c.api); },
       {},
       {},
       Thread::worker},
      {140,
       http::verb::get,
       "/api/runs/{id}",
       "a run's record and its files",
       [](const Call& c) { return run(c.api, c.args[0]); },
       {},
       {},
       Thread::worker},
      {150,
       http::verb::get,
       "/api/runs/{id}/report.html",
       "a run's paper-style report (HTML, made on the job worker once the run has ended; ?wait=0: 202 and the job's state until "
       "made)",
       run_report,
       kReportQuery,
       {},
       Thread::worker},
      {200,
       http::verb::get,
       "/api/runs/{id}/events",
       "a run's events from byte ?offset=N of events.jsonl (0 when not given): operator events whole, loop statistics "
       "summarised per second; follow next_offset",
       run_events,
       kEventsQuery,
       {},
       Thread::worker},
      {210,
       http::verb::get,
       "/api/runs/{id}/{file}",
       "one file of a run",
       [](const Call& c) { return run_file(c.api, c.args[0], c.args[1]); },
       {},
       {},
       Thread::worker},
  };
}

}  // namespace hil::bench::api
