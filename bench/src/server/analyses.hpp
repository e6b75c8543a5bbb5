// What the server makes of a recorded run, off the io thread (jobs.hpp): its paper-style report
// and its analyses against a plant model. A run's telemetry.csv is a measurement file as it is
// (physics.md section 4: t_s, theta_cmd_deg, p_meas_mpa, theta_motor_deg, p_ref_mpa, other
// columns ignored; a period without a reading repeats the last values, never nan), so an analysis
// is `hilbench compare` / `hilbench diagnose` on RUN_DIR/telemetry.csv: the same library calls
// (analysis::run_compare, analysis::run_diagnose), quiet, with the outputs in
//   RUN_DIR/analyses/<id>/   report.html, compare.json or diagnosis.json (+ fitted_model.yaml),
//                            analysis.json (what was asked, when, the result's summary)
// written into RUN_DIR/analyses/.<id>.tmp and renamed into place at the end: an analysis folder
// is complete or absent. A failure (a bad file, or the server stopping it at a cancel point)
// leaves RUN_DIR/analyses/<id>/failed.json alone (what was asked, when, why), made the same way,
// so that the run's list still shows it failed after a restart; a server killed mid-job leaves
// only the .tmp, which the next server's start removes.
#pragma once

#include <atomic>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "jobs.hpp"

namespace hil::bench {

inline constexpr const char* kAnalysisKinds[] = {"compare", "diagnose"};

struct AnalysisSpec {
  std::filesystem::path run_dir;
  std::string id;    // a plain name, unique in the run (next_analysis_id)
  std::string kind;  // compare | diagnose
  std::string model;
  std::filesystem::path model_file;
  std::filesystem::path model_dir;  // set: model_file must resolve inside it when the job runs (a link made since is refused)
};

std::filesystem::path analysis_dir(const std::filesystem::path& run_dir, const std::string& id);

// "<kind>_<model>_<n>" with the smallest n >= 1 that names neither a folder (finished or .tmp) of
// the run nor one of `taken` (the jobs queued or running for it).
std::string next_analysis_id(const std::filesystem::path& run_dir, const std::string& kind, const std::string& model,
                             const std::vector<std::string>& taken);

// What a diagnosis of a telemetry.csv of `csv_bytes` holds in memory at its peak (its rows as
// numbers, their replays and fits): at most 2.5 x the file plus 16 MiB. Measured with `hilbench
// diagnose` on 23 to 325 MB of 1 kHz telemetry: 1.6 to 2.5 x plus 16 MiB, the most where more
// parameters are fitted (docs/benchmarks.md). The server checks it against
// ApiOptions::max_diagnose_bytes before it queues a diagnosis: its memory is locked.
std::uint64_t diagnose_memory_bytes(std::uint64_t csv_bytes);

// The reason a job gives when the server stopped it at a cancel point.
inline constexpr const char* kServerStopped = "server stopped";

// The job's work: runs the analysis into its .tmp folder, renames it into place, and returns the
// summary kept in analysis.json (compare: fit, RMSE, noise floor, the residual's signature;
// diagnose: the verdict, the effects added and the first round's candidates). `cancel` raised:
// stops at the analysis's next cancel point (hil/analysis/cancel.hpp). Throws naming the cause (a
// telemetry.csv the measurement reader refuses, a model that does not load; kServerStopped when
// cancelled), with the .tmp folder removed and failed.json written in the analysis's folder.
nlohmann::json run_analysis(const AnalysisSpec& spec, const JobQueue::Progress& progress,
                            const std::atomic<bool>* cancel = nullptr);

// The run's finished analyses (done, or failed with a failed.json), oldest first, as the API's
// JOB objects (a failure's reason is its "error"); a folder with neither file readable is listed
// with state "failed" and the reason.
std::vector<nlohmann::json> finished_analyses(const std::filesystem::path& run_dir);

// The job's work for GET /api/runs/ID/report.html: write_run_report into RUN_DIR/report.html.tmp,
// renamed to report.html (removed on failure). `cancel` raised: stops before the next chunk of
// the telemetry's rows and throws kServerStopped, having written nothing.
nlohmann::json make_run_report(const std::filesystem::path& run_dir, const JobQueue::Progress& progress = {},
                               const std::atomic<bool>* cancel = nullptr);
// Whether RUN_DIR/report.html is that run's report: made after run.json was last written (run.json
// is rewritten only by the run's end or by a server finding the run interrupted).
bool run_report_current(const std::filesystem::path& run_dir);

// Throws std::runtime_error naming the file when one of the files a report or an analysis reads
// in the run folder (run.json, telemetry.csv, telemetry.mcap, events.jsonl) is a symbolic link or not a regular
// file: it is never followed (a link to /etc/shadow had its first line quoted in the error).
void refuse_linked_run_files(const std::filesystem::path& run_dir);

// Removes what a server that died during a job left in the run folders: RUN_DIR/report.html.tmp
// and RUN_DIR/analyses/.*.tmp. Returns how many it removed.
std::size_t remove_job_leftovers(const std::filesystem::path& runs_dir);

}  // namespace hil::bench
