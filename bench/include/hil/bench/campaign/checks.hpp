// A campaign's verdicts: its `checks:` block (README, "Checks: a campaign's verdict") says what
// each run must show, as metric thresholds over the run's summary (stall per reversal, IAE, gap
// estimate error at reversals, interlock trips, ...) and as signal checks over time windows
// opened by events ("pressure within 5 % of the reference 1.5 s after every reference change",
// "no safe state", "gap estimate within 10 % of the true gap from the 2nd reversal after each gap
// change"). One evaluator, RunChecks, is fed every period's record by whatever runs the campaign
// (`hilbench sim`, a served run's recorder, a sweep point), so all of them give the same verdicts.
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "hil/bench/campaign/run_metrics.hpp"

namespace hil::cfg {
class Node;
}

namespace hil::bench {

struct Campaign;
struct TelemetryRecord;

// What a metric check reads from the run's summary (RunSummary) at the end of the run.
enum class CheckMetric : std::uint8_t {
  iae_mpa_s,
  rmse_mpa,
  stall_s_per_reversal,        // reduced over reversals from_reversal..n
  stall_vs_none,               // mean: mean stall over the `none` run's mean; max: the largest per-reversal ratio
  touch_changes_per_reversal,  // reduced over reversals
  gap_error_deg,               // |estimate - true| held at each reversal, reduced (default from the 2nd)
  gap_error_rel,               // the same over the true gap
  interlock_trips,             // trips of the pressure interlocks (a served run: its own; sim and sweep: the defaults')
  compensation_events,
};

// What a signal check reads from each period's record.
enum class CheckSignal : std::uint8_t {
  pressure_error_mpa,  // |p_meas - p_ref|
  pressure_error_rel,  // |p_meas - p_ref| / p_ref
  gap_error_deg,       // |gap_est - gap_true| (a rig without the true gap: no value)
  gap_error_rel,       // the same over the true gap
  safe_state,          // 1 in the safe state, else 0
};

// Events that open a signal check's windows (bits, a check may name several).
enum CheckEvent : std::uint8_t {
  kEventStart = 1u << 0,            // the run's first period
  kEventReferenceChange = 1u << 1,  // the reference moved this period (a step, every period of a ramp)
  kEventReversal = 1u << 2,         // a reversal of the reference (campaign.reversals_s)
  kEventGapChange = 1u << 3,        // the true gap changed (programmed or injected)
};

enum class CheckReduce : std::uint8_t { mean, max };

struct CheckSpec {
  std::string name;
  std::string where;              // "file:line" of the item, for messages
  std::vector<std::string> runs;  // empty: every run
  bool signal_check = false;
  CheckMetric metric = CheckMetric::iae_mpa_s;
  CheckSignal signal = CheckSignal::pressure_error_mpa;
  // Metric: the first reversal counted (1-based; 0: the metric's default). Signal: the window
  // opens at this reversal after its event (0: at the event), plus delay_s.
  int from_reversal = 0;
  int to_reversal = 0;  // metric: the last reversal counted (0: the run's last)
  CheckReduce reduce = CheckReduce::mean;
  std::uint8_t after = kEventStart;                        // signal: CheckEvent bits
  double delay_s = 0;                                      // signal: the window opens this long after the event
  double for_s = std::numeric_limits<double>::infinity();  // and lasts this long at most (until the next event)
  std::optional<double> min, max;

  bool applies_to(const std::string& run) const;
  std::string quantity() const;  // "stall_vs_none", "signal pressure_error_rel", for messages
};

// The items of a campaign's `checks:` list; `runs` are the campaign's run names. Throws cfg::Error
// naming file:line:key.
std::vector<CheckSpec> parse_checks(const cfg::Node& list, const std::vector<std::string>& runs);

enum class Verdict : std::uint8_t { pass, fail, skipped };
const char* to_string(Verdict v) noexcept;

struct CheckResult {
  std::string check, run;
  Verdict verdict = Verdict::skipped;
  double value = std::numeric_limits<double>::quiet_NaN();  // the metric, or the signal's worst value
  double at_s = std::numeric_limits<double>::quiet_NaN();   // signal: where the worst value was
  long samples = 0;                                         // signal: periods inside the windows
  std::optional<double> min, max;
  std::string message;  // what was measured against what, or why it was skipped
  nlohmann::json to_json() const;
};

// The results of one run's checks: counts and whether all passed (skipped ones do not fail).
struct CheckTally {
  long passed = 0, failed = 0, skipped = 0;
};
CheckTally tally(const std::vector<CheckResult>& results);
nlohmann::json checks_json(const std::vector<CheckResult>& results);  // {"passed", "failed", "skipped", "results": [...]}

// Counts the trips the bench's default pressure interlocks (SafetyConfig{}) would have made on
// a run without interlocks (a simulation): one each time the debounced check starts tripping.
class InterlockCounter {
 public:
  InterlockCounter();
  ~InterlockCounter();
  InterlockCounter(const InterlockCounter&) = delete;
  InterlockCounter& operator=(const InterlockCounter&) = delete;
  void add(const TelemetryRecord& r) noexcept;
  long trips() const noexcept { return trips_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  long trips_ = 0;
  bool tripping_ = false;
};

// A check's verdict while its run goes on (RunChecks::live), on the rows seen so far:
//  - fail: a signal check's worst value is past its limit; that value only grows, so the end says
//    fail too (decided);
//  - pass / skipped: a signal check none of whose windows can open again (`after: start` only,
//    its window closed): what the end will say (decided);
//  - passing: a signal check whose windows so far closed within its limit, and another may open
//    (the next reference step, gap change or reversal): "pass so far";
//  - pending: a window is open or has not opened yet, or a metric of the whole run (stall per
//    reversal, IAE, ...), which is judged at the run's end only.
enum class LiveVerdict : std::uint8_t { pending, passing, pass, fail, skipped };
const char* to_string(LiveVerdict v) noexcept;

struct LiveCheck {
  CheckResult result;  // a signal check: what finish() would say on the rows so far; a metric: its limits only
  LiveVerdict verdict = LiveVerdict::pending;
  bool decided = false;            // the run's end gives the same verdict (fail, pass, skipped)
  bool at_end = false;             // a metric of the whole run: pending until the run's end
  nlohmann::json to_json() const;  // CheckResult's fields, "verdict" the live one, "decided", "at_end"
};

// One run's checks, fed each period's record. add() does not allocate.
class RunChecks {
 public:
  RunChecks(const Campaign& c, const std::string& run);
  void add(const TelemetryRecord& r) noexcept;
  // The verdicts: the signal checks from what add() saw, the metric checks from `summary` (a
  // stall of NaN: the rig does not measure the valve). `other` gives the summary of another run
  // of the campaign (stall_vs_none), or null when it did not run.
  using OtherRun = std::function<const RunSummary*(const std::string& run)>;
  std::vector<CheckResult> finish(const RunSummary& summary, long interlock_trips, const OtherRun& other) const;
  bool empty() const { return specs_.empty(); }
  const std::string& run() const { return run_; }

  // A signal check's window state (one per check; nothing is kept for a metric check).
  struct Window {
    double event_t_s = std::numeric_limits<double>::quiet_NaN();  // the window's start (NaN: not open)
    int reversals_since = 0;
    double worst = -std::numeric_limits<double>::infinity(), worst_t_s = 0;
    long samples = 0, valued = 0;
    bool inside = false;  // the last record was inside a window
    long closed = 0;      // windows that have closed
  };
  // What add() has seen: small and of fixed size once the first record is in, so another thread
  // can be handed a copy (assigning it to a copy of the same run does not allocate).
  struct Progress {
    std::vector<Window> windows;
    std::size_t next_reversal = 0;                          // reversals passed
    double t_s = std::numeric_limits<double>::quiet_NaN();  // the last record's time
    long rows = 0;
  };
  const Progress& progress() const noexcept { return progress_; }
  // The verdicts as they stand after the records of `p` (a copy of progress(), maybe taken on
  // another thread: live() reads only `p` and what the constructor set). Costs O(checks), whatever
  // the run's length.
  std::vector<LiveCheck> live(const Progress& p) const;

 private:
  CheckResult signal_result(std::size_t i, const Window& w) const;  // finish()'s verdict of signal check i
  bool may_open_again(std::size_t i, const Window& w, const Progress& p) const;
  std::vector<const CheckSpec*> specs_;
  Progress progress_;  // windows: one per check
  std::vector<double> reversals_s_;
  bool have_prev_ = false;
  double prev_p_ref_pa_ = 0, prev_gap_rad_ = 0;
  std::string run_;
};

// JUnit XML (the Jenkins/GitLab/GitHub reading, attributes as the Jenkins xUnit JUnit schema
// allows them): a testsuite per campaign, a testcase per run and check (a run without checks: one
// testcase "completed"), the failing value and limit in the failure's message, and the campaign's
// report as an attachment ([[ATTACHMENT|path]]). A run that did not complete (or never ran: a
// campaign stopped before it) is a testcase "completed" with an <error> naming its outcome and
// reason, and its checks that were never judged are errors too, never skipped: CI must not go
// green on a bench that did nothing. A campaign file that could not be read is a testsuite of
// one testcase with the error (file:line: ...). A testcase's time is its run's wall time (a
// check's verdict takes the whole run).
struct JunitRun {
  std::string name;
  double wall_s = 0;
  std::vector<CheckResult> results;
  std::string outcome = "completed";  // or aborted, error, stopped, interrupted, "not run"
  std::string reason;                 // why it did not complete
};
struct JunitSuite {
  std::string campaign;
  std::string report_path;  // as the CI should find it (absolute, or relative to its workspace), or empty
  double wall_s = 0;
  std::vector<JunitRun> runs;
  std::string error;  // the campaign could not be read: its file in `campaign`, the message here; no runs
};
std::string junit_xml(const std::vector<JunitSuite>& suites);
// What every file junit_xml writes holds near its start: an existing --junit file without it is
// not one the tool wrote, and is not replaced (hil/output_path.hpp).
inline constexpr std::string_view kJunitSignature = "<testsuites name=\"hilbench\"";

}  // namespace hil::bench
