#include "hil/bench/campaign/run_report.hpp"

#include <algorithm>
#include <cstdio>
#include <optional>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/campaign/run_marks.hpp"
#include "hil/bench/rt/run_record.hpp"
#include "sim_report.hpp"
#include "hil/config.hpp"
#include "hil/csv_reader.hpp"
#include "hil/table_reader.hpp"
#include "hil/units.hpp"

namespace hil::bench {
namespace {

// A run's telemetry: telemetry.csv, or telemetry.mcap where the CSV is not kept (same rows).
std::filesystem::path telemetry_file(const std::filesystem::path& dir) {
  std::error_code ec;
  if (!std::filesystem::exists(dir / "telemetry.csv", ec) && std::filesystem::exists(dir / "telemetry.mcap", ec))
    return dir / "telemetry.mcap";
  return dir / "telemetry.csv";
}

using nlohmann::json;
using plant::kNaN;

// The error of a snapshot in run.json, which cfg names as the file it was copied from
// ("FILE:LINE:COLUMN: ..."): said as the copy, whose line and column they are, lest the file on
// disk be blamed (it may be fine, edited since, or gone). Empty when `e` is not about `copied`.
std::string snapshot_error(const cfg::Error& e, const std::filesystem::path& copied, const std::filesystem::path& record,
                           const char* key) {
  const std::string what = e.what(), head = copied.string() + ":";
  if (copied.empty() || what.rfind(head, 0) != 0) return "";
  return record.string() + ": " + key + ":" + what.substr(head.size()) + " (" + key + " is the copy of " + copied.string() +
         " that run.json keeps from the run's start; that file was not read)";
}

Campaign campaign_of(const RunRecord& run, const std::filesystem::path& dir) {
  const std::string& yaml = run.config.campaign_yaml;
  const std::filesystem::path file = run.config.campaign_file;
  if (yaml.empty() || file.empty()) throw std::runtime_error(dir.string() + "/run.json: the config snapshot has no campaign");
  const std::filesystem::path record = dir / "run.json";
  try {
    // The plant as the run had it; a run.json from before the plant's snapshot names only the
    // campaign, whose plant path resolves from where the campaign file was.
    if (!run.config.plant_yaml.empty())
      return load_campaign_text(yaml, file.filename().string(), file.parent_path(), run.config.plant_yaml, run.config.plant_file);
    return load_campaign_text(yaml, file.filename().string(), file.parent_path());
  } catch (const cfg::Error& e) {
    // load_campaign_text names the campaign's text as parent/filename, i.e. `file`.
    std::string what = snapshot_error(e, file.parent_path() / file.filename(), record, "config.campaign_yaml");
    if (what.empty() && !run.config.plant_yaml.empty())
      what = snapshot_error(e, run.config.plant_file, record, "config.plant_yaml");
    if (what.empty()) throw;  // a plant file on disk (a run.json without the plant's snapshot): its own error
    throw cfg::Error(what);
  }
}

// Reads the runs' telemetry chunk by chunk into their digests, reporting the fraction of all
// the files' bytes read; the cancel flag is looked at between chunks.
class TelemetryStream {
 public:
  TelemetryStream(const std::vector<std::filesystem::path>& files, const RunReportOptions& options) : options_(options) {
    for (const auto& f : files) {
      std::error_code ec;
      const auto size = std::filesystem::file_size(f, ec);
      total_bytes_ += ec ? 0 : size;  // unreadable: the reader names the file when it opens it
    }
  }

  RunOutcome digest(const Campaign& c, const std::filesystem::path& csv, const std::string& name) {
    using telemetry::Col;
    // The schema's columns up to theta_target_deg, requested in its order so that values[index(c)]
    // is column c: the measurement columns are required, the rest optional (a rig without the
    // truth leaves those out).
    CsvRequest request;
    request.increasing = std::string(telemetry::name(Col::t_s));
    for (std::size_t k = 0; k <= telemetry::index(Col::theta_target_deg); ++k)
      (k <= telemetry::index(Col::p_ref_mpa) ? request.required : request.optional).emplace_back(telemetry::kColumns[k].name);
    TableReader reader(csv, request, telemetry::kTopic);
    const auto present = [&](Col c) { return static_cast<bool>(reader.header().present[telemetry::index(c)]); };
    const bool chamber_known = present(Col::p_chamber_mpa), valve_known = present(Col::theta_valve_deg);
    RunDigest digest(c);
    CsvChunk t;
    std::size_t rows = 0;
    while (!cancelled() && reader.next(t)) {
      const auto col = [&](Col c, std::size_t i, double fallback) {
        const auto& v = t.values[telemetry::index(c)];
        return v.empty() ? fallback : v[i];
      };
      // The observer's states are codes -1, 0, +1, made ints: any other value is no telemetry of
      // ours, and one beyond int's range (1e300) was undefined behaviour in the conversion.
      const auto code = [&](Col c, std::size_t i) {
        const double v = col(c, i, 0);
        if (v != -1 && v != 0 && v != 1) {
          char msg[120];
          std::snprintf(msg, sizeof msg, ": must be -1, 0 or 1 (the observer's state), got %.6g", v);
          throw CsvError(reader.where(t.lines[i], telemetry::name(c)) + msg);
        }
        return static_cast<int>(v);
      };
      for (std::size_t i = 0; i < t.rows(); ++i) {
        // Each column read back through the record's one table (set_field); what a row may lack:
        // the observer's codes and the compensation default to 0, the rest to NaN; a rig without
        // the chamber's truth gives the measured pressure for it (IAE then holds the sensor noise
        // too); without the valve angle a stall cannot be seen (set unknown below).
        TelemetryRecord rec;
        for (std::size_t k = 0; k <= telemetry::index(Col::theta_target_deg); ++k) {
          const auto c = static_cast<Col>(k);
          const bool code_column = c == Col::touch_state || c == Col::motion_intention;
          const double value = code_column ? code(c, i) : col(c, i, c == Col::comp_deg ? 0 : kNaN);
          set_field(rec, c, value);
        }
        if (!chamber_known) rec.step.p_chamber_pa = rec.step.p_meas_pa;
        digest.add(rec);
      }
      rows += t.rows();
      if (options_.progress && total_bytes_ > 0)
        options_.progress(std::min(1.0, static_cast<double>(done_bytes_ + reader.bytes_read()) / total_bytes_));
    }
    if (cancelled()) throw Cancelled("the report was cancelled");
    done_bytes_ += reader.bytes_read();
    RunOutcome out = digest.finish(name);
    if (!valve_known || rows == 0) {
      out.summary.stall_s_total = kNaN;
      out.summary.stall_fraction = kNaN;
      for (auto& rev : out.summary.reversals) rev.stall_s = kNaN;
    }
    return out;
  }

 private:
  bool cancelled() const { return options_.cancel != nullptr && options_.cancel->load(std::memory_order_relaxed); }

  const RunReportOptions& options_;
  std::uint64_t total_bytes_ = 0, done_bytes_ = 0;
};

}  // namespace

std::vector<RecordedRun> write_run_report(const std::vector<std::filesystem::path>& run_dirs,
                                          const std::filesystem::path& out_file, const RunReportOptions& options) {
  if (run_dirs.empty()) throw std::invalid_argument("no run folder given");
  std::vector<std::filesystem::path> files;
  for (const auto& dir : run_dirs) files.push_back(telemetry_file(dir));
  TelemetryStream telemetry(files, options);
  std::vector<RecordedRun> runs;
  std::optional<Campaign> campaign;
  std::string recorded_by;  // the command that recorded them all, or "" when not one
  for (const auto& dir : run_dirs) {
    const RunRecord run = read_run_record(dir);
    recorded_by = runs.empty() || run.recorded_by == recorded_by ? run.recorded_by : "";
    const Campaign c = campaign_of(run, dir);
    if (campaign && c.name != campaign->name) {
      throw std::invalid_argument(dir.string() + ": a run of campaign '" + c.name + "', the others are of '" + campaign->name +
                                  "' (a report compares runs of one campaign)");
    }
    if (!campaign) campaign = c;
    RecordedRun r;
    r.dir = dir;
    r.outcome = std::string(to_string(run.outcome));
    r.reason = run.reason.value_or("");
    std::string name = run.run;
    for (const auto& other : runs) {
      if (other.digest.name == name) name += " (" + dir.filename().string() + ")";
    }
    r.digest = telemetry.digest(c, telemetry_file(dir), name);
    // What the operator and the loop did, as events.jsonl recorded it (marked in the report).
    r.digest.marks = marks_from_events(dir / "events.jsonl", r.digest.summary.duration_s);
    r.digest.marks_recorded = true;
    r.digest.detail_run = dir.filename().string();  // served as /api/runs/<folder name>
    runs.push_back(std::move(r));
  }
  std::vector<RunOutcome> outcomes;
  // Who recorded them as run.json says (a record older than the key says nobody: "Recorded runs").
  std::string note = recorded_by.empty() ? "Recorded runs:" : "Recorded by " + recorded_by + ":";
  for (const auto& r : runs) {
    outcomes.push_back(r.digest);
    note += " " + r.digest.name + " " + r.outcome + (r.reason.empty() ? "" : " (" + r.reason + ")") + " [" +
            r.dir.filename().string() + "];";
  }
  note.back() = '.';
  write_sim_report(*campaign, outcomes, out_file, "hilbench report", note);
  return runs;
}

}  // namespace hil::bench
