#include "hil/bench/run_report.hpp"

#include <fstream>
#include <optional>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "hil/bench/campaign.hpp"
#include "hil/bench/sim_report.hpp"
#include "hil/csv_reader.hpp"
#include "hil/units.hpp"

namespace hil::bench {
namespace {

using nlohmann::json;
using plant::kNaN;

json read_run_json(const std::filesystem::path& dir) {
  const auto file = dir / "run.json";
  std::ifstream in(file);
  if (!in) throw std::runtime_error(dir.string() + ": no run.json (not a run folder of hilbench serve)");
  json j = json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (!j.is_object() || !j.contains("config") || !j["config"].is_object()) {
    throw std::runtime_error(file.string() + ": not a run record (no config snapshot)");
  }
  return j;
}

Campaign campaign_of(const json& run, const std::filesystem::path& dir) {
  const json& cfg = run["config"];
  const std::string yaml = cfg.value("campaign_yaml", "");
  const std::filesystem::path file = cfg.value("campaign_file", "");
  if (yaml.empty() || file.empty()) throw std::runtime_error(dir.string() + "/run.json: the config snapshot has no campaign");
  // Relative paths in the campaign (its plant) resolve from where the campaign file was.
  return load_campaign_text(yaml, file.filename().string(), file.parent_path());
}

RunOutcome digest_of(const Campaign& c, const std::filesystem::path& csv, const std::string& name) {
  using units::deg_to_rad;
  using units::mpa_to_pa;
  const CsvChunk t = read_csv(csv, {{"t_s", "theta_cmd_deg", "p_meas_mpa", "theta_motor_deg", "p_ref_mpa"},
                                    {"theta_valve_deg", "gap_true_deg", "touch_state", "motion_intention", "comp_deg",
                                     "gap_est_deg", "p_chamber_mpa", "theta_target_deg"},
                                    "t_s"});
  const auto col = [&](std::size_t k, std::size_t i, double fallback) {
    return t.values[k].empty() ? fallback : t.values[k][i];
  };
  RunDigest digest(c);
  for (std::size_t i = 0; i < t.rows(); ++i) {
    StepRecord r;
    r.t_s = t.values[0][i];
    r.theta_cmd_rad = deg_to_rad(t.values[1][i]);
    r.p_meas_pa = mpa_to_pa(t.values[2][i]);
    r.theta_motor_rad = deg_to_rad(t.values[3][i]);
    r.p_ref_pa = mpa_to_pa(t.values[4][i]);
    r.theta_valve_rad = deg_to_rad(col(5, i, kNaN));
    r.gap_true_rad = deg_to_rad(col(6, i, kNaN));
    r.touch = static_cast<decltype(r.touch)>(col(7, i, 0));
    r.intention = static_cast<decltype(r.intention)>(col(8, i, 0));
    r.comp_rad = deg_to_rad(col(9, i, 0));
    r.gap_est_rad = deg_to_rad(col(10, i, kNaN));
    // A rig without the chamber's truth: the error is the measured one (IAE then holds the
    // sensor noise too); without the valve angle a stall cannot be seen (set unknown below).
    r.p_chamber_pa = t.values[11].empty() ? r.p_meas_pa : mpa_to_pa(t.values[11][i]);
    digest.add(r, deg_to_rad(col(12, i, kNaN)));
  }
  RunOutcome out = digest.finish(name);
  if (t.values[5].empty()) {
    out.summary.stall_s_total = kNaN;
    out.summary.stall_fraction = kNaN;
    for (auto& rev : out.summary.reversals) rev.stall_s = kNaN;
  }
  return out;
}

}  // namespace

std::vector<RecordedRun> write_run_report(const std::vector<std::filesystem::path>& run_dirs, const std::filesystem::path& out_file) {
  if (run_dirs.empty()) throw std::invalid_argument("no run folder given");
  std::vector<RecordedRun> runs;
  std::optional<Campaign> campaign;
  for (const auto& dir : run_dirs) {
    const json run = read_run_json(dir);
    const Campaign c = campaign_of(run, dir);
    if (campaign && c.name != campaign->name) {
      throw std::invalid_argument(dir.string() + ": a run of campaign '" + c.name + "', the others are of '" + campaign->name +
                                  "' (a report compares runs of one campaign)");
    }
    if (!campaign) campaign = c;
    RecordedRun r;
    r.dir = dir;
    r.outcome = run.value("outcome", "?");
    r.reason = run["reason"].is_string() ? run["reason"].get<std::string>() : "";
    std::string name = run.value("run", dir.filename().string());
    for (const auto& other : runs) {
      if (other.digest.name == name) name += " (" + dir.filename().string() + ")";
    }
    r.digest = digest_of(c, dir / "telemetry.csv", name);
    runs.push_back(std::move(r));
  }
  std::vector<RunOutcome> outcomes;
  std::string note = "Recorded by hilbench serve:";
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
