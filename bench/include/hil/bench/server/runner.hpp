// The campaign runner: runs a campaign's runs one after the other on a rig, each in its own
// real-time loop thread with its own recorder and run folder
//   <runs_dir>/<UTC start>_<campaign>_<run>/  telemetry.csv, events.jsonl, run.json
// and answers the operator's requests (status, stop, abort, injections) from any thread.
// Not real-time: it sets the loop up, waits for it, and writes run.json.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/rt/rig_config.hpp"
#include "hil/bench/rt/rt_loop.hpp"
#include "hil/bench/rt/run_folder.hpp"  // InsufficientStorage, utc_iso
#include "hil/bench/rt/run_record.hpp"

namespace hil::bench {

// Refusals the API turns into 4xx: the runner's state does not allow the request.
class Conflict : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};
// A start request's field that cannot run as given ("runs", "speed"): the API's 400 names it, so
// a client can point at it (every 400 of the API carries the field at fault).
class BadField : public std::invalid_argument {
 public:
  BadField(std::string field_name, const std::string& what) : std::invalid_argument(what), field(std::move(field_name)) {}
  std::string field;
};
// A run folder's run.json says "running" but no live process holds the run's lock: the process
// that recorded it (`hilbench serve` or `hilbench run`) died during it (kill -9, a crash, power).
// Rewrites run.json to outcome "interrupted" with what is really on disk (a half-written last
// line is cut off and counted) and appends an event. `found_by` names who found it in the
// reason ("a server started", "hilbench report"). Safe while another process records in the
// same folder: a run whose lock is held is left alone.
// The runs of a runs folder; returns the folders it marked.
std::vector<std::filesystem::path> mark_interrupted_runs(const std::filesystem::path& runs_dir,
                                                         const std::string& found_by = "a server started");
// One run folder; true when it marked it.
bool mark_interrupted_run(const std::filesystem::path& dir, const std::string& found_by);

// The end of the last run a server knows: in the status as "last_run", so that a console opened
// or reconnected after it (a restart after a crash included) says what became of the run it shows.
struct LastRun {
  std::string dir;  // the run folder's name
  std::string campaign, run, start_utc, stop_utc;
  Outcome outcome = Outcome::completed;
  std::optional<std::string> reason;
  std::optional<std::string> trip;  // the interlock that ended it, or "operator abort"
  static LastRun of(const std::string& dir, const RunRecord& record);
  nlohmann::json to_json() const;
};
// The newest run folder (by its name, which starts with the run's UTC start) whose run.json says
// it ended; nullopt when there is none. At a server's start, after mark_interrupted_runs.
std::optional<LastRun> newest_ended_run(const std::filesystem::path& runs_dir);

// A start's `speed` (loop periods per dT of wall time): from a hundredth of real time to a hundred
// times it, and never a loop period longer than kMaxWallPeriodS of wall time. The loop waits a
// whole period before it reads an abort, a stop or SIGTERM, so a slower pace leaves the bench
// deaf (speed 1e-9 ran a period for 11 days; 1e-300 overflowed the period's conversion).
inline constexpr double kMinSpeed = 0.01, kMaxSpeed = 100, kMaxWallPeriodS = 1.0;
// Empty when `speed` can pace a campaign of control period `period_s`; else why not.
std::string speed_problem(double speed, double period_s);

// What an injection may ask of the loop (API, ctl, console): every value finite and within these,
// so that what the loop records stays a number (a bias or noise of 1e308 kPa made the reading inf
// and then NaN, and telemetry.csv held 'nan' that no reader takes).
inline constexpr double kMaxInjectionS = 86400, kMaxInjectedGapDeg = 10, kMaxSensorBiasKpa = 10000, kMaxSensorNoiseKpa = 1000;
// Throws BadField (named as the API's field: gap_deg, bias_kpa, rms_kpa, duration_s) for a value
// outside those.
void check_injection(const LoopRequest& request);

struct StartRequest {
  Campaign campaign;
  RigConfig rig;
  std::vector<std::string> runs;  // empty: all, in the campaign's order
  double speed = 1.0;             // loop periods per dT of wall time; simulated rigs (Rig::simulated) only
  std::string source;             // where the campaign came from ("configs/campaigns/x.yaml", "posted")
};

struct RunnerOptions {
  std::filesystem::path runs_dir = "runs";
  std::string version = "0";
  std::string mlock_warning;                             // what lock_memory() said at start ("" = memory locked)
  std::string recorded_by = "hilbench serve";            // the command, in run.json and telemetry.csv's header
  std::function<void(const TelemetryRecord&)> on_row;    // recorder thread, every row
  std::function<void(const nlohmann::json&)> on_notice;  // run started / finished; any thread
  drv::CanTransportFactory can_transport;                // the CAN rigs' bus; empty: SocketCAN (tests: a loopback bus)
  std::optional<LastRun> last_run;                       // what the runs folder held at start (newest_ended_run)
};

class CampaignRunner {
 public:
  explicit CampaignRunner(RunnerOptions options);
  ~CampaignRunner();  // aborts a running campaign and waits for it
  CampaignRunner(const CampaignRunner&) = delete;
  CampaignRunner& operator=(const CampaignRunner&) = delete;

  // Validates and starts; returns at once. Throws Conflict when a campaign runs, BadField
  // for a request that cannot run (unknown run name, speed on a hardware rig), InsufficientStorage
  // when the runs folder cannot hold the campaign's telemetry.
  void start(StartRequest request);
  // Ends the campaign after the current period (outcome "stopped"). Throws Conflict when idle.
  void stop();
  // Safety abort: safe state, then the end (outcome "aborted"). Throws Conflict when idle.
  // Returns the reason the campaign will end with: the first abort's, when one is under way.
  std::string abort(const std::string& reason);
  // An injection for the running loop. Throws Conflict when no loop runs, invalid_argument when
  // the rig cannot do it.
  void inject(const LoopRequest& request);

  bool running() const;
  void wait();  // until the campaign thread has finished
  nlohmann::json status() const;

  // A run (its folder's name) that ended in this process but whose final run.json the disk
  // refused, so that file still says "running". Tries the write again first: `written` says
  // whether the file is the record now. Until a restart restores it from events.jsonl, the API
  // shows this record instead of the file's. Nothing for any other run.
  struct UnrecordedEnd {
    RunRecord record;
    bool written = false;
  };
  std::optional<UnrecordedEnd> unrecorded_end(const std::string& run_dir_name);

 private:
  struct Active;
  void run_campaign(std::shared_ptr<Active> a);
  void run_one(Active& a, std::size_t index);
  void notice(const nlohmann::json& j) const;

  RunnerOptions o_;
  mutable std::mutex mutex_;
  std::shared_ptr<Active> active_;   // the running campaign, or null
  nlohmann::json last_;              // the last finished campaign
  std::optional<LastRun> last_run_;  // the last ended run (this server's, or the runs folder's at start)
  std::thread thread_;
  std::mutex unrecorded_mutex_;                  // not mutex_: a retried write must not hold up status()
  std::map<std::string, RunRecord> unrecorded_;  // by run folder name; see unrecorded_end
};

}  // namespace hil::bench
