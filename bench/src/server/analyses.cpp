#include "analyses.hpp"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>

#include <spdlog/spdlog.h>

#include "hil/analysis/compare.hpp"
#include "hil/analysis/diagnose.hpp"
#include "hil/bench/campaign/run_report.hpp"
#include "hil/bench/server/runner.hpp"
#include "hil/config.hpp"
#include "hil/line_file.hpp"
#include "hil/json_file.hpp"
#include "request_guard.hpp"

namespace hil::bench {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

json number(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

fs::path tmp_dir(const fs::path& run_dir, const std::string& id) { return run_dir / "analyses" / ("." + id + ".tmp"); }

json compare_summary(const analysis::ResidualReport& r) {
  json j = analysis::headline_json(r);  // compare.json's own headline
  j["signature"] = r.signature;
  return j;
}

json diagnose_summary(const analysis::Diagnosis& d) {
  auto params = [](const analysis::CandidateResult& c) {
    json list = json::array();
    for (const auto& p : c.parameters) {
      list.push_back({{"block", p.effect}, {"key", p.key}, {"value", number(p.value)}, {"uncertainty", number(p.sigma)}});
    }
    return list;
  };
  json added = json::array();
  for (const auto& c : d.added) added.push_back({{"effect", c.effect}, {"variant", c.variant}, {"parameters", params(c)}});
  json candidates = json::array();
  if (!d.rounds.empty()) {
    for (const auto& c : d.rounds.front().ranking) {
      candidates.push_back({{"effect", c.effect},
                            {"variant", c.variant},
                            {"fit_after_pct", number(c.fit_after_pct)},
                            {"delta_bic", number(c.delta_bic)},
                            {"earns_place", c.earns_place}});
    }
  }
  json not_identifiable = json::array();
  for (const auto& n : d.not_identifiable) not_identifiable.push_back({{"effect", n.effect}, {"reason", n.reason}});
  return {{"verdict", d.verdict},
          {"explained", d.explained},
          {"fit_before_pct", number(d.fit_before_pct)},
          {"fit_after_pct", number(d.fit_after_pct)},
          {"noise_floor_fit_pct", number(d.noise_floor_fit_pct)},
          {"added", added},
          {"candidates", candidates},
          {"not_identifiable", not_identifiable},
          {"rows_left_out", d.before.rows_left_out},
          {"run_notes", d.before.run_notes},  // the run's own record: fault windows left out, gap inputs
          {"summary", d.summary}};
}

}  // namespace

fs::path analysis_dir(const fs::path& run_dir, const std::string& id) { return run_dir / "analyses" / id; }

std::string next_analysis_id(const fs::path& run_dir, const std::string& kind, const std::string& model,
                             const std::vector<std::string>& taken) {
  for (int n = 1;; ++n) {
    const std::string id = kind + "_" + model + "_" + std::to_string(n);
    std::error_code ec;
    if (fs::exists(analysis_dir(run_dir, id), ec) || fs::exists(tmp_dir(run_dir, id), ec)) continue;
    if (std::find(taken.begin(), taken.end(), id) != taken.end()) continue;
    return id;
  }
}

namespace {

// The failure's record, in place of the results: the folder holds failed.json alone. Best effort:
// a disk that refuses it must not hide the failure's own reason, which the job keeps.
void record_failure(const AnalysisSpec& spec, const std::string& reason, const std::string& started_utc) {
  const fs::path tmp = tmp_dir(spec.run_dir, spec.id);
  std::error_code ec;
  try {
    fs::remove_all(tmp, ec);
    fs::create_directories(tmp);
    const json record = {{"id", spec.id},
                         {"kind", spec.kind},
                         {"model", spec.model},
                         {"state", "failed"},
                         {"reason", reason},
                         {"started_utc", started_utc},
                         {"finished_utc", utc_iso(std::chrono::system_clock::now())}};
    replace_file(tmp / "failed.json", record.dump(2) + "\n");
    fs::rename(tmp, analysis_dir(spec.run_dir, spec.id));
  } catch (const std::exception& e) {
    fs::remove_all(tmp, ec);
    spdlog::warn("analysis {} of {}: cannot record its failure: {}", spec.id, spec.run_dir.string(), e.what());
  }
}

}  // namespace

json run_analysis(const AnalysisSpec& spec, const JobQueue::Progress& progress, const std::atomic<bool>* cancel) {
  const fs::path tmp = tmp_dir(spec.run_dir, spec.id);
  const fs::path data = spec.run_dir / "telemetry.csv";
  const std::string started_utc = utc_iso(std::chrono::system_clock::now());
  std::error_code ec;
  fs::remove_all(tmp, ec);
  fs::create_directories(tmp);
  try {
    json result;
    refuse_linked_run_files(spec.run_dir);
    // The model is checked again as the job starts: a link to a file outside the models' folder
    // made after the request was accepted is refused, never read (its error would quote it).
    if (!spec.model_dir.empty() && !resolves_inside(spec.model_file, spec.model_dir)) {
      throw std::runtime_error("model '" + spec.model + "': " + spec.model_file.string() +
                               " is a symbolic link to a file outside " + spec.model_dir.string() + ": not read");
    }
    if (spec.kind == "compare") {
      analysis::CompareOptions o;
      o.model_file = spec.model_file;
      o.data_file = data;
      o.out_dir = tmp;
      o.quiet = true;
      o.on_progress = [&progress](double fraction, std::size_t) { progress(fraction); };
      o.cancel = cancel;
      result = compare_summary(analysis::run_compare(o));
    } else if (spec.kind == "diagnose") {
      analysis::DiagnoseOptions o;
      o.model_file = spec.model_file;
      o.data_files = {data};
      o.out_dir = tmp;
      o.write_model = tmp / "fitted_model.yaml";
      o.quiet = true;
      // One fitter thread: the worker shares the machine with the loop's recorder and the io
      // thread, which must stay responsive while a diagnosis runs.
      o.settings.threads = 1;
      o.settings.cancel = cancel;
      result = diagnose_summary(analysis::run_diagnose(o));
    } else {
      throw std::invalid_argument("unknown analysis kind '" + spec.kind + "'");
    }
    const json record = {{"id", spec.id},
                         {"kind", spec.kind},
                         {"model", spec.model},
                         {"model_file", spec.model_file.string()},
                         {"data_file", data.string()},
                         {"state", "done"},
                         {"started_utc", started_utc},
                         {"finished_utc", utc_iso(std::chrono::system_clock::now())},
                         {"result", result}};
    replace_file(tmp / "analysis.json", record.dump(2) + "\n");
    fs::rename(tmp, analysis_dir(spec.run_dir, spec.id));
    return result;
  } catch (const analysis::Cancelled&) {
    record_failure(spec, kServerStopped, started_utc);
    throw std::runtime_error(kServerStopped);
  } catch (const std::exception& e) {
    record_failure(spec, e.what(), started_utc);
    throw;
  } catch (...) {
    record_failure(spec, "the analysis failed with an exception that is not a std::exception", started_utc);
    throw;
  }
}

std::vector<json> finished_analyses(const fs::path& run_dir) {
  std::vector<fs::path> dirs;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(run_dir / "analyses", ec)) {
    const std::string name = e.path().filename().string();
    std::error_code ec2;
    if (e.symlink_status(ec2).type() == fs::file_type::directory && cfg::plain_name(name) && name.front() != '.')
      dirs.push_back(e.path());
  }
  std::vector<std::pair<std::string, json>> out;
  for (const auto& d : dirs) {
    const std::string id = d.filename().string();
    // A done analysis has analysis.json; a failed one failed.json alone.
    const auto present = [&](const char* f) { return fs::symlink_status(d / f, ec).type() != fs::file_type::not_found; };
    const bool failed = !present("analysis.json") && present("failed.json");
    const std::string file = failed ? "failed.json" : "analysis.json";
    try {
      // Not through a link, bounded before it is parsed, and never quoted (request_guard.hpp).
      json j = read_json_inside(run_dir, {"analyses", id, file});
      if (!j.is_object()) throw std::runtime_error((d / file).string() + ": not a JSON object");
      j["id"] = id;
      if (failed) {
        j["state"] = "failed";
        j["error"] = j.value("reason", "");
        j.erase("reason");
      }
      out.emplace_back(j.value("finished_utc", ""), std::move(j));
    } catch (const std::exception& e) {
      out.emplace_back("", json{{"id", id}, {"state", "failed"}, {"error", e.what()}});  // names the file
    }
  }
  std::stable_sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<json> list;
  for (auto& [when, j] : out) list.push_back(std::move(j));
  return list;
}

void refuse_linked_run_files(const fs::path& run_dir) {
  // Opened as the routes open them (open_inside: no link at any part, no FIFO or device), then
  // closed: the report and the analyses read these files by name.
  for (const char* name : {"run.json", "telemetry.csv", "telemetry.mcap", "events.jsonl"}) {
    bool missing = false;
    const OpenedFile f = open_inside(run_dir.parent_path(), {run_dir.filename().string(), name}, &missing);
    if (f.fd >= 0) ::close(f.fd);
  }
}

bool run_report_current(const fs::path& run_dir) {
  std::error_code ec, ec2;
  const auto made = fs::last_write_time(run_dir / "report.html", ec);
  const auto recorded = fs::last_write_time(run_dir / "run.json", ec2);
  return !ec && !ec2 && made >= recorded;
}

std::uint64_t diagnose_memory_bytes(std::uint64_t csv_bytes) { return csv_bytes * 5 / 2 + (std::uint64_t{16} << 20); }

json make_run_report(const fs::path& run_dir, const JobQueue::Progress& progress, const std::atomic<bool>* cancel) {
  const auto part = run_dir / "report.html.tmp";  // a half-written report is never served or listed
  std::error_code ec;
  try {
    refuse_linked_run_files(run_dir);
    RunReportOptions options;
    options.progress = progress;
    options.cancel = cancel;
    const auto runs = write_run_report({run_dir}, part, options);
    fs::rename(part, run_dir / "report.html");
    json j = json::object();
    if (!runs.empty()) j["outcome"] = runs.front().outcome;
    return j;
  } catch (const Cancelled&) {
    fs::remove(part, ec);
    throw std::runtime_error(kServerStopped);
  } catch (...) {
    fs::remove(part, ec);
    throw;
  }
}

std::size_t remove_job_leftovers(const fs::path& runs_dir) {
  std::size_t removed = 0;
  std::error_code ec;
  for (const auto& run : fs::directory_iterator(runs_dir, ec)) {
    if (!run.is_directory()) continue;
    std::error_code ec2;
    if (fs::remove(run.path() / "report.html.tmp", ec2)) ++removed;
    for (const auto& e : fs::directory_iterator(run.path() / "analyses", ec2)) {
      const std::string name = e.path().filename().string();
      if (name.front() == '.' && e.path().extension() == ".tmp") {
        std::error_code ec3;
        fs::remove_all(e.path(), ec3);
        ++removed;
      }
    }
  }
  return removed;
}

}  // namespace hil::bench
