// A run's record, run.json in its folder: written when the run starts (outcome running), again
// when it ends, and rewritten by a later server that finds the process died during the run
// (interrupted). Read by the API's run list, `hilbench report` and that later server. The file's
// keys are written and read here only: one struct, one to_json, one from_json.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace hil::bench {

// How a run ended, in run.json's "outcome" (and a campaign's: its worst run's). In order of how
// bad: a campaign ends with the last of its runs' outcomes in this order.
enum class Outcome : std::uint8_t { completed, stopped, aborted, error, interrupted, running };
std::string_view to_string(Outcome o) noexcept;
// The outcome named by `text` (run.json, the API); error for a name it does not know.
Outcome outcome_from(std::string_view text) noexcept;

struct RunRecord {
  // Written at the start.
  std::string version, host;
  std::int64_t pid = 0;
  std::string recorded_by;  // the command that recorded the run: "hilbench serve", "hilbench run" ("": not said)
  std::string campaign, run;
  std::int64_t run_index = 0, runs_in_campaign = 0;
  std::string rig_name, rig_kind;
  std::string start_utc;
  std::optional<std::string> stop_utc;  // null while running
  Outcome outcome = Outcome::running;
  std::optional<std::string> reason;  // null: nothing to say (completed)
  double period_s = 0, duration_s = 0, speed = 1;
  struct Config {  // what the run was made of, as loaded (files as absolute paths)
    std::string campaign_source, campaign_file, campaign_yaml, rig_file, rig_yaml;
    // The campaign's plant file and its text: the run's report is made from the plant the run
    // had, even once the file is edited or gone (empty when a run.json lacks it: no plant text kept).
    std::string plant_file, plant_yaml;
  } config;

  // Written at the end (absent before).
  struct Trip {
    std::string reason;
    double t_s = 0;
    std::optional<double> value, limit;  // null when the trip has none (an operator abort)
    // The run's longest time between two periods' starts (a stalled host or loop) and the t of
    // the period that ended it: beside the trip, since a stall explains many trips.
    std::optional<double> longest_gap_ms, longest_gap_t_s;
  };
  bool ended = false;  // the end keys below are written ("trip": null when there was none)
  std::optional<Trip> trip;
  nlohmann::json rig_health;  // the rig's RigHealth at the end (null: the loop never started)
  std::optional<std::int64_t> periods_run;
  nlohmann::json loop;  // the loop's timing statistics and scheduling (absent: never started)

  // Written at the end, or by the server that found the run interrupted (then only what the
  // files on disk show: a count nobody knows is left out, never written as 0).
  struct Telemetry {
    std::string file = "telemetry.csv";
    std::optional<std::uint64_t> rows_written, rows_lost, rows_unwritten, events_lost, events_unwritten, ring_rows;
    std::optional<std::string> write_error;     // written as null when the end found none
    bool write_error_known = false;             // the end wrote write_error (null or text)
    std::optional<std::int64_t> rows_expected;  // interrupted runs: what the whole run would have had
  };
  std::optional<Telemetry> telemetry;
  nlohmann::json interrupted;  // found_utc, last_write_utc, bytes_trimmed (null: not interrupted)
  // The campaign's verdicts on the run (campaign/checks.hpp, checks_json): written at the end when
  // the campaign has checks (null: none asked).
  nlohmann::json checks;

  nlohmann::json to_json() const;
  // Throws std::runtime_error naming `origin` and the key that is missing or of the wrong type.
  static RunRecord from_json(const nlohmann::json& j, const std::string& origin);
};

// DIR/run.json; throws naming the file when it is absent, not JSON, or not a run record.
RunRecord read_run_record(const std::filesystem::path& dir);
// DIR/run.json, atomically (a reader sees the old record or the new one, whole).
void write_run_record(const std::filesystem::path& dir, const RunRecord& record);

}  // namespace hil::bench
