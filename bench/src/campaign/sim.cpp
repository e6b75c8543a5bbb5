#include "hil/bench/campaign/sim.hpp"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <system_error>
#include <thread>

#include "sim_report.hpp"
#include "hil/config.hpp"
#include "hil/file_lock.hpp"
#include "hil/line_file.hpp"
#include "hil/minmax_decimator.hpp"
#include "hil/parallel_for.hpp"
#include "hil/progress_line.hpp"
#include "hil/units.hpp"

namespace hil::bench {
namespace {

using Clock = std::chrono::steady_clock;

// At most 2 x 5000 buckets of two rows (three where a column has a gap): a report plot of a run
// holds at most ~20 000 points.
constexpr std::size_t kReportBuckets = 5000;

// The telemetry columns the campaign report plots.
constexpr telemetry::Col kReportColumns[] = {
    telemetry::Col::p_ref_mpa,       telemetry::Col::p_meas_mpa,      telemetry::Col::touch_state,
    telemetry::Col::theta_motor_deg, telemetry::Col::theta_valve_deg, telemetry::Col::theta_cmd_deg,
    telemetry::Col::gap_est_deg,     telemetry::Col::gap_true_deg,    telemetry::Col::theta_target_deg};

// The report's series, min/max decimated as the run goes over shared buckets, so they share their
// times (hil/minmax_decimator.hpp). A column without a finite value is left empty: no line.
class ReportDecimator {
 public:
  void add(const TelemetryRow& row) {
    const double t = row[telemetry::index(telemetry::Col::t_s)];
    for (std::size_t i = 0; i < std::size(kReportColumns); ++i) values_[i] = row[telemetry::index(kReportColumns[i])];
    decimator_.add(t, values_);
    ++rows_;
  }
  std::vector<ReportSeries> take() const {
    std::vector<double> t;
    std::vector<std::vector<double>> values;
    decimator_.take(t, values);
    std::vector<ReportSeries> out(values.size());
    for (std::size_t i = 0; i < values.size(); ++i) {
      out[i].name = std::string(telemetry::name(kReportColumns[i]));
      if (std::none_of(values[i].begin(), values[i].end(), [](double v) { return std::isfinite(v); })) continue;
      out[i].t_s = t;
      out[i].value = std::move(values[i]);
      out[i].samples = rows_;
    }
    return out;
  }

 private:
  MinMaxDecimator decimator_{kReportBuckets, std::size(kReportColumns)};
  std::array<double, std::size(kReportColumns)> values_{};
  std::size_t rows_ = 0;
};

// A run as execute() leaves it: its outcome, and what its checks need once every run is through
// (stall_vs_none reads the `none` run's summary).
struct Executed {
  RunOutcome outcome;
  nlohmann::json summary;  // summary.json, without the checks yet
  std::unique_ptr<RunChecks> checks;
  long interlock_trips = 0;
};

Executed execute(const Campaign& c, const RunSpec& run, const std::filesystem::path& dir, bool telemetry,
                 std::atomic<long>& steps_done, const std::atomic<bool>* cancel) {
  const auto t0 = Clock::now();
  RunDigest digest(c);
  auto checks = std::make_unique<RunChecks>(c, run.name);
  InterlockCounter interlocks;
  std::unique_ptr<CsvWriter> csv;
  if (telemetry) {
    csv = std::make_unique<CsvWriter>(
        dir / "telemetry.csv", telemetry_columns(ColumnSet::sim),
        std::vector<std::pair<std::string, std::string>>{{"source", "hilbench sim"}, {"campaign", c.name}, {"run", run.name}});
  }
  TelemetryRow row;
  simulate_run(
      c, run,
      [&](const TelemetryRecord& r) {
        digest.add(r);
        checks->add(r);
        interlocks.add(r);
        if (csv) csv->row({row.data(), telemetry_row(r, ColumnSet::sim, row)});
        if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) throw Cancelled("cancelled");
      },
      &steps_done);
  if (csv) csv->close();
  RunOutcome out = digest.finish(run.name);
  out.wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
  nlohmann::json summary = out.summary.to_json();
  summary["campaign"] = c.name;
  summary["run"] = run.name;
  summary["compensation"] = ctl::compensation_name(run.controller.compensation);
  summary["compensator"] = run.controller.compensator;
  summary["sensor_noise_kpa"] = c.sensor_noise_rms_pa / units::kPaPerKpa;
  summary["wall_s"] = out.wall_s;
  return {std::move(out), std::move(summary), std::move(checks), interlocks.trips()};
}

// The lock a sim holds on its unpublished folder ".NAME.tmp-PID" while it works, beside it (not
// in it: the folder is published as it is).
std::filesystem::path tmp_dir_lock(const std::filesystem::path& tmp_dir) {
  return tmp_dir.parent_path() / (tmp_dir.filename().string() + ".lock");
}

// ".NAME.tmp-PID" folders whose process is gone (killed before it could clean up). Alive is a held
// lock: the PID alone cannot say, as a sim in another PID namespace (a container, another host on
// shared storage) is a PID this process does not see, and a dead sim's PID may be reused. A
// folder without a lock file (a sim of a version before the lock) is judged by its PID.
void remove_dead_tmp_dirs(const std::filesystem::path& out_dir, const std::string& name) {
  const std::string prefix = "." + name + ".tmp-";
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(out_dir, ec)) {
    const std::string f = e.path().filename().string();
    if (!e.is_directory() || f.rfind(prefix, 0) != 0) continue;
    const std::string pid_text = f.substr(prefix.size());
    char* end = nullptr;
    const long pid = std::strtol(pid_text.c_str(), &end, 10);
    if (pid_text.empty() || *end != '\0' || pid <= 0 || pid == ::getpid()) continue;
    const auto lock = tmp_dir_lock(e.path());
    if (std::filesystem::exists(lock, ec)) {
      if (!FileLock::free(lock)) continue;  // its sim is working
    } else if (::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) {
      continue;  // alive, or not ours to judge
    }
    std::filesystem::remove_all(e.path(), ec);
    std::filesystem::remove(lock, ec);
  }
}

// Puts the finished folder `tmp_dir` at `final_dir` in one step: the old result (if any) and the
// new one trade places (renameat2 RENAME_EXCHANGE), then the old one, now at tmp_dir, goes. A
// process killed at any moment leaves one whole result at final_dir; before, the old one was
// removed first, and a kill during that removal (a large folder takes seconds) lost both. A file
// system without the exchange gets two renames, the old result parked at ".NAME.old-PID" between
// them (a kill there leaves it to be found, never removed).
void publish_dir(const std::filesystem::path& tmp_dir, const std::filesystem::path& final_dir) {
  std::error_code ec;
  if (!std::filesystem::exists(std::filesystem::symlink_status(final_dir, ec))) {
    std::filesystem::rename(tmp_dir, final_dir);
    return;
  }
  if (::renameat2(AT_FDCWD, tmp_dir.c_str(), AT_FDCWD, final_dir.c_str(), RENAME_EXCHANGE) == 0) {
    std::filesystem::remove_all(tmp_dir, ec);
    return;
  }
  if (errno != EINVAL && errno != ENOSYS)
    throw std::system_error(errno, std::generic_category(),
                            "cannot put " + tmp_dir.string() + " in place of " + final_dir.string());
  std::string parked_name = ".";  // built in place: GCC 12 warns (-Wrestrict, wrongly) on "." + a temporary
  parked_name += final_dir.filename().string();
  parked_name += ".old-" + std::to_string(::getpid());
  const auto parked = final_dir.parent_path() / parked_name;
  std::filesystem::remove_all(parked);
  std::filesystem::rename(final_dir, parked);
  std::filesystem::rename(tmp_dir, final_dir);
  std::filesystem::remove_all(parked, ec);
}

// `dir` is what a former `hilbench sim` of this campaign left (campaign.yaml, report.html, run
// folders of summary.json and telemetry.csv) or nothing: only then may a new run replace it.
// A campaign's name picks the folder, so `name: src` with `--out .` must not wipe ./src.
void require_replaceable_output(const std::filesystem::path& dir) {
  std::error_code ec;
  const auto st = std::filesystem::symlink_status(dir, ec);
  if (!std::filesystem::exists(st)) return;
  const auto refuse = [&](const std::string& why) {
    throw std::runtime_error(dir.string() + " exists and " + why +
                             ", so it is not replaced: move it away, or choose another --out");
  };
  if (!std::filesystem::is_directory(st)) refuse("is not a folder");
  const auto ours = [](const std::filesystem::path& name, std::initializer_list<const char*> files) {
    const std::string f = name.filename().string();
    if (f.rfind('.', 0) == 0 && f.find(".tmp") != std::string::npos) return true;  // a writer's temporary
    return std::find(files.begin(), files.end(), f) != files.end();
  };
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.is_directory(ec) && !e.is_symlink(ec)) {
      for (const auto& f : std::filesystem::directory_iterator(e.path())) {
        if (!f.is_regular_file(ec) || !ours(f.path(), {"summary.json", "telemetry.csv"}))
          refuse("holds " + f.path().string() + ", which hilbench sim does not write");
      }
    } else if (!e.is_regular_file(ec) || e.is_symlink(ec) || !ours(e.path(), {"campaign.yaml", "report.html"})) {
      refuse("holds " + e.path().string() + ", which hilbench sim does not write");
    }
  }
}

}  // namespace

struct RunDigest::Impl {
  RunMetrics metrics;
  ReportDecimator report;
};

RunDigest::RunDigest(const Campaign& c)
    : impl_(std::make_unique<Impl>(Impl{RunMetrics(c.reversals_s, c.reference_moves, c.period_s, kMotionThresholdRadS), {}})) {}

RunDigest::~RunDigest() = default;

void RunDigest::add(const TelemetryRecord& r) {
  impl_->metrics.add(r.step);
  impl_->report.add(telemetry_row(r));
}

RunOutcome RunDigest::finish(std::string run_name) {
  return {std::move(run_name), impl_->metrics.finish(), impl_->report.take(), 0, {}, {}, false, {}};
}

SimulatedRun::SimulatedRun(const Campaign& c, const RunSpec& run)
    : telemetry_(2),  // one record a period, taken before the next
      events_(16),    // no operator, no interlocks: nothing to report but what nobody reads
      requests_(1),
      loop_(c, run, rig_, SafetyConfig::none(), LoopConfig{},
            std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(c.period_s)), telemetry_, events_,
            requests_, /*now: simulated time, nothing to time*/ nullptr) {
  rig_.configure({&c, c.period_s, c.reference_pa.at(0.0), c.gap_rad.at(0.0)});
  rig_.activate();
  loop_.begin(t_);
}

bool SimulatedRun::advance() noexcept {
  if (loop_.end() != LoopEnd::running) return false;
  // Each period wakes on its deadline and ends there: no latency, no compute time, no overrun.
  loop_.cycle(t_, t_);
  loop_.finish_cycle(t_);
  t_ += loop_.wall_period();
  return true;
}

RunSummary summarise_run(const Campaign& c, const RunSpec& run) {
  return summarise_run(c, run, [](const TelemetryRecord&) {});
}

CampaignOutcome run_campaign(const Campaign& c, const SimOptions& options) {
  std::vector<const RunSpec*> runs;
  for (const auto& r : c.runs) {
    if (options.only_runs.empty() ||
        std::find(options.only_runs.begin(), options.only_runs.end(), r.name) != options.only_runs.end()) {
      runs.push_back(&r);
    }
  }
  if (runs.empty()) throw std::runtime_error("no run of campaign '" + c.name + "' matches --runs");

  // Everything goes into a hidden folder first and is renamed into place at the end; the folder
  // goes again on any failure or cancel, and leftovers of processes that died are cleared.
  if (!cfg::plain_name(c.name)) throw std::invalid_argument("campaign name '" + c.name + "' is no plain name");
  const auto t0 = Clock::now();
  std::filesystem::create_directories(options.out_dir);
  remove_dead_tmp_dirs(options.out_dir, c.name);
  const auto final_dir = options.out_dir / c.name;
  require_replaceable_output(final_dir);  // before the runs: say it now, not after minutes of work
  const auto tmp_dir = options.out_dir / ("." + c.name + ".tmp-" + std::to_string(::getpid()));
  const FileLock tmp_lock(tmp_dir_lock(tmp_dir), /*remove_when_released=*/true);  // released after the folder's guard
  struct RemoveUnlessKept {
    std::filesystem::path dir;
    bool keep = false;
    ~RemoveUnlessKept() {
      std::error_code ec;
      if (!keep) std::filesystem::remove_all(dir, ec);
    }
  } tmp_guard{tmp_dir};
  std::filesystem::remove_all(tmp_dir);
  for (const auto* r : runs) std::filesystem::create_directories(tmp_dir / r->name);
  replace_file(tmp_dir / "campaign.yaml", c.yaml_text);

  CampaignOutcome outcome;
  outcome.runs.resize(runs.size());
  std::vector<Executed> executed(runs.size());
  std::atomic<long> steps_done{0};
  const long steps_total = std::lround(c.duration_s / c.period_s) * static_cast<long>(runs.size());
  // The runs on every core (hil/parallel_for.hpp); the first run's error, if any, is thrown.
  auto run_all = [&] {
    hil::parallel_for(runs.size(), hil::worker_threads(runs.size()), [&](std::size_t i) {
      executed[i] = execute(c, *runs[i], tmp_dir / runs[i]->name, options.telemetry, steps_done, options.cancel);
    });
  };
  if (options.progress && c.duration_s * runs.size() >= 120) {
    // Long campaign: a progress line while the workers run.
    std::atomic<bool> runs_over{false};
    std::thread progress([&] {
      const double simulated_s = c.duration_s * static_cast<double>(runs.size());
      ProgressLine line("sim " + c.name);
      auto show = [&] {
        const double f = static_cast<double>(steps_done.load()) / steps_total;
        line.update(f, [&] {
          const double wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
          char detail[96];
          std::snprintf(detail, sizeof detail, "(%.0f of %.0f s simulated, %.0fx real time)", f * simulated_s, simulated_s,
                        f * simulated_s / std::max(wall_s, 1e-9));
          return std::string(detail);
        });
      };
      while (!runs_over.load()) {
        std::this_thread::sleep_for(std::chrono::milliseconds(250));
        show();
      }
      show();  // where it ended: 100 % once every run is through, less when one failed
    });
    try {
      run_all();
    } catch (...) {
      runs_over.store(true);
      progress.join();
      throw;
    }
    runs_over.store(true);
    progress.join();
  } else {
    run_all();
  }
  // The verdicts, once every run is through (a check may compare with another run), into each
  // run's summary.json.
  const auto other = [&](const std::string& name) -> const RunSummary* {
    for (const auto& e : executed)
      if (e.outcome.name == name) return &e.outcome.summary;
    return nullptr;
  };
  for (std::size_t i = 0; i < runs.size(); ++i) {
    Executed& e = executed[i];
    e.outcome.checks = e.checks->finish(e.outcome.summary, e.interlock_trips, other);
    if (!c.checks.empty()) e.summary["checks"] = checks_json(e.outcome.checks);
    replace_file(tmp_dir / runs[i]->name / "summary.json", e.summary.dump(2) + "\n");
  }
  for (std::size_t i = 0; i < runs.size(); ++i) outcome.runs[i] = std::move(executed[i].outcome);
  for (const auto& r : outcome.runs) outcome.simulated_s += r.summary.duration_s;
  write_sim_report(c, outcome.runs, tmp_dir / "report.html");
  require_replaceable_output(final_dir);  // again: something may have come in the meantime
  publish_dir(tmp_dir, final_dir);
  tmp_guard.keep = true;
  outcome.dir = final_dir;
  outcome.wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
  return outcome;
}

}  // namespace hil::bench
