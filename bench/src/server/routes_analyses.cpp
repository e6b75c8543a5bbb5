// Analyses of an ended run against a plant model (compare, diagnose): queued on the job worker,
// listed with their state, and their files once done.
#include <algorithm>
#include <cmath>

#include <spdlog/spdlog.h>

#include "analyses.hpp"
#include "api_router.hpp"
#include "api_run_files.hpp"
#include "hil/config.hpp"

namespace hil::bench::api {
namespace {

const FieldSpecs kAnalysisBody = {
    {"kind", FieldType::text, "", -INFINITY, INFINITY, false, "compare or diagnose"},
    {"model", FieldType::text, "", -INFINITY, INFINITY, false, "a plant model's name from GET /api/models"},
};

// An analysis of the run, from the jobs (queued, running, failed) or from its folder (done).
std::optional<json> find_analysis(const ApiServer::Impl& api, const std::string& id, const std::string& aid) {
  if (const auto job = api.jobs.find(id, aid); job && job->kind != "report" && job->state != JobState::done)
    return job->to_json();
  for (auto& a : finished_analyses(api.options.runs_dir / id)) {
    if (a.value("id", "") == aid) return a;
  }
  return std::nullopt;
}

// What every analysis in a list or alone carries: where its report is, once there is one.
json with_links(json a, const std::string& run) {
  const std::string base = "/api/runs/" + run + "/analyses/" + a.value("id", "");
  a["run"] = run;
  a["url"] = base;
  if (a.value("state", "") == "done") a["report"] = base + "/report.html";
  return a;
}

Reply analyses(const ApiServer::Impl& api, const std::string& id) {
  const auto dir = api.options.runs_dir / id;
  require_run(api, id);
  json list = json::array();
  std::vector<std::string> on_disk;
  for (auto& a : finished_analyses(dir)) {
    on_disk.push_back(a.value("id", ""));
    list.push_back(with_links(std::move(a), id));
  }
  for (const auto& job : api.jobs.of_run(id)) {
    if (job.kind == "report" || std::find(on_disk.begin(), on_disk.end(), job.id) != on_disk.end()) continue;
    list.push_back(with_links(job.to_json(), id));
  }
  return json_reply(http::status::ok, {{"run", id}, {"analyses", list}});
}

Reply start_analysis(const Call& c) {
  ApiServer::Impl& api = c.api;
  const std::string& id = c.args[0];
  if (const std::string why = api.refusing(); !why.empty())
    throw ApiError{http::status::service_unavailable, "not accepting jobs", why};
  // The body first: a malformed request is named whatever the run.
  const Fields body = c.body();
  const std::string kind = body.text("kind", "");
  const std::vector<std::string> kinds(std::begin(kAnalysisKinds), std::end(kAnalysisKinds));
  if (std::find(kinds.begin(), kinds.end(), kind) == kinds.end()) {
    const std::string hint = kind.empty() ? "" : cfg::closest(kind, kinds);
    throw ApiError{http::status::bad_request, "bad field",
                   "'kind' must be compare or diagnose" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)"), "kind"};
  }
  const std::string model = body.text("model", "");
  const auto names = yaml_stems(api.options.plant_dir);
  if (model.empty()) {
    throw ApiError{http::status::bad_request, "bad field", "'model' is required: a plant model's name from GET /api/models",
                   "model"};
  }
  if (!cfg::plain_name(model) || std::find(names.begin(), names.end(), model) == names.end()) {
    const std::string hint = cfg::closest(model, names);
    throw ApiError{http::status::not_found, "unknown model",
                   "'model': '" + model + "' is not a plant model in " + api.options.plant_dir.string() +
                       (hint.empty() ? "" : " (did you mean '" + hint + "'?)"),
                   "model"};
  }
  const auto model_file = api.options.plant_dir / (model + ".yaml");
  if (!resolves_inside(model_file, api.options.plant_dir)) {
    throw ApiError{http::status::conflict, "model file not read",
                   "'model': " + model_file.string() + " is a symbolic link to a file outside " + api.options.plant_dir.string() +
                       ": not read (the bench reads and quotes no file outside its folders)",
                   "model"};
  }
  const auto dir = ended_run(api, id);
  if (!std::filesystem::is_regular_file(dir / "telemetry.csv")) {
    throw ApiError{http::status::unprocessable_entity, "no measurement", "run '" + id + "' has no telemetry.csv"};
  }
  try {
    refuse_linked_run_files(dir);
  } catch (const std::exception& e) {
    throw ApiError{http::status::unprocessable_entity, "file not read", e.what()};
  }
  if (kind == "diagnose") {
    std::error_code ec;
    const std::uint64_t csv_bytes = std::filesystem::file_size(dir / "telemetry.csv", ec);
    const std::uint64_t need = ec ? 0 : diagnose_memory_bytes(csv_bytes);
    if (need > api.options.max_diagnose_bytes) {
      const auto mb = [](std::uint64_t bytes) { return std::to_string(std::llround(bytes / 1048576.0)) + " MB"; };
      throw ApiError{http::status::unprocessable_entity, "too large for this server",
                     "run '" + id + "': a diagnosis of its telemetry.csv (" + mb(csv_bytes) + ") holds about " + mb(need) +
                         " in memory, locked while it runs; this server allows " + mb(api.options.max_diagnose_bytes) +
                         " (hilbench serve --max-diagnose-mb). A compare reads it in chunks and has no such limit; "
                         "or run hilbench diagnose --data on a copy of the run's folder elsewhere"};
    }
  }
  // The same analysis already waiting or running: that one is the answer, not a second copy.
  std::vector<std::string> live;
  for (const auto& job : api.jobs.of_run(id)) {
    if (job.state != JobState::queued && job.state != JobState::running) continue;
    if (job.kind == kind && job.model == model) {
      return json_reply(http::status::accepted, {{"analysis", with_links(job.to_json(), id)},
                                                 {"note", "the same analysis is already " + std::string(to_string(job.state))}});
    }
    live.push_back(job.id);
  }
  AnalysisSpec spec;
  spec.run_dir = dir;
  spec.kind = kind;
  spec.model = model;
  spec.model_file = std::filesystem::absolute(model_file);
  spec.model_dir = std::filesystem::absolute(api.options.plant_dir);
  spec.id = next_analysis_id(dir, kind, model, live);
  JobStatus s;
  s.run = id;
  s.id = spec.id;
  s.kind = kind;
  s.model = model;
  JobStatus queued;
  try {
    queued = api.jobs.submit(s, [spec](const JobQueue::Progress& progress, const std::atomic<bool>& cancel) {
      return run_analysis(spec, progress, &cancel);
    });
  } catch (const JobRefused& e) {
    throw ApiError{http::status::service_unavailable, "cannot queue the job", e.what()};
  }
  spdlog::info("run {}: {} against {} queued as {}", id, kind, model, spec.id);
  return json_reply(http::status::accepted, {{"analysis", with_links(queued.to_json(), id)}});
}

Reply analysis(const ApiServer::Impl& api, const std::string& id, const std::string& aid) {
  const auto a = cfg::plain_name(id) && cfg::plain_name(aid) ? find_analysis(api, id, aid) : std::nullopt;
  if (!a) {
    throw ApiError{http::status::not_found, "unknown analysis",
                   "run '" + id + "' has no analysis '" + aid + "' (GET /api/runs/" + id + "/analyses lists them)"};
  }
  return json_reply(http::status::ok, {{"analysis", with_links(*a, id)}});
}

Reply analysis_file(const ApiServer::Impl& api, const std::string& id, const std::string& aid, const std::string& file) {
  const auto a = cfg::plain_name(id) && cfg::plain_name(aid) ? find_analysis(api, id, aid) : std::nullopt;
  if (!a) {
    throw ApiError{http::status::not_found, "unknown analysis",
                   "run '" + id + "' has no analysis '" + aid + "' (GET /api/runs/" + id + "/analyses lists them)"};
  }
  const std::string state = a->value("state", "");
  if (state == "queued" || state == "running") return json_reply(http::status::accepted, {{"analysis", with_links(*a, id)}});
  if (state != "done") throw ApiError{http::status::unprocessable_entity, "the analysis failed", a->value("error", "")};
  const auto path = analysis_dir(api.options.runs_dir / id, aid) / file;
  const std::string missing = "analysis '" + aid + "' of run '" + id + "' has no file '" + file + "'";
  if (!cfg::plain_name(file)) throw ApiError{http::status::not_found, "unknown file", missing};
  const std::vector<std::string> parts = {id, "analyses", aid, file};
  if (path.extension() == ".html") return html_file(api.options.runs_dir, parts);
  Reply r = opened_file(api.options.runs_dir, parts, missing);
  r.content_type = path.extension() == ".json"   ? "application/json"
                   : path.extension() == ".yaml" ? "application/yaml"
                                                 : "text/plain";
  r.extra_header = "attachment; filename=\"" + file + "\"";
  return r;
}

}  // namespace

std::vector<Route> analysis_routes() {
  return {
      {160,
       http::verb::get,
       "/api/runs/{id}/analyses",
       "a run's analyses against plant models: queued, running, done or failed",
       [](const Call& c) { return analyses(c.api, c.args[0]); },
       {},
       {},
       Thread::worker},
      {170,
       http::verb::post,
       "/api/runs/{id}/analyses",
       "analyse an ended run against a plant model: {kind: compare | diagnose, model}",
       start_analysis,
       {},
       kAnalysisBody,
       Thread::worker},
      {180,
       http::verb::get,
       "/api/runs/{id}/analyses/{analysis}",
       "one analysis: its state, progress, error or result",
       [](const Call& c) { return analysis(c.api, c.args[0], c.args[1]); },
       {},
       {},
       Thread::worker},
      {190,
       http::verb::get,
       "/api/runs/{id}/analyses/{analysis}/{file}",
       "a file of a finished analysis: report.html, compare.json or diagnosis.json, fitted_model.yaml, analysis.json",
       [](const Call& c) { return analysis_file(c.api, c.args[0], c.args[1], c.args[2]); },
       {},
       {},
       Thread::worker},
  };
}

}  // namespace hil::bench::api
