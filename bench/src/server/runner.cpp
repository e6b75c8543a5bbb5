#include "hil/bench/server/runner.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <fstream>
#include <optional>
#include <semaphore>

#include <spdlog/spdlog.h>

#include "hil/bench/rt/recorder.hpp"
#include "hil/bench/rt/rig_registry.hpp"
#include "hil/bench/rt/rt_thread.hpp"
#include "hil/config.hpp"
#include "hil/file_lock.hpp"
#include "hil/json_file.hpp"
#include "hil/line_file.hpp"
#include "hil/text_file.hpp"
#include "hil/units.hpp"
#include "run_folder.hpp"
#include "run_verdicts.hpp"

namespace hil::bench {
namespace {

using nlohmann::json;
using SysClock = std::chrono::system_clock;

// How far a run is, by its loop's last period: the end of that period (none yet: 0).
double run_time_s(const LoopSnapshot& snap, const Campaign& c) {
  return snap.periods == 0 ? 0 : std::min(snap.t_s + c.period_s, c.duration_s);
}

std::string utc(SysClock::time_point t, const char* format) {
  const std::time_t s = SysClock::to_time_t(t);
  std::tm tm{};
  gmtime_r(&s, &tm);
  char buf[64];
  std::strftime(buf, sizeof buf, format, &tm);
  return buf;
}

std::string hostname() {
  char buf[256] = {};
  gethostname(buf, sizeof buf - 1);
  return buf;
}

// The whole file or the old one, never a half-written one; no .tmp is left behind on failure.

// Space kept free in each run folder while the run lasts, and given back just before the final
// run.json is written: so a disk that the telemetry filled still takes the run's honest record.
constexpr std::uintmax_t kReserveBytes = 1u << 20;
// A loop telemetry row in telemetry.csv (about 110-140 characters) and in telemetry.mcap (about
// 410 bytes: the JSON with its keys, the record, its index entry; paper_adaptive's 18 000 rows
// and 1 255 events made a 7.3 MB file).
constexpr double kBytesPerRow = 560;

std::filesystem::path unique_dir(const std::filesystem::path& base) {
  std::filesystem::path p = base;
  for (int i = 2; std::filesystem::exists(p); ++i) p = base.string() + "_" + std::to_string(i);
  std::filesystem::create_directories(p);
  return p;
}

std::string fmt(const char* format, double a, double b = 0, double c = 0) {
  char buf[200];
  std::snprintf(buf, sizeof buf, format, a, b, c);
  return buf;
}

// The reason of a trip in the operator's words.
std::string describe_trip(const RunLoop& loop) {
  const double t = loop.trip_t_s();
  switch (loop.trip()) {
    case Trip::overpressure:
      return fmt("overpressure: p_meas %.4f MPa above the %.4f MPa limit at t = %.3f s", units::pa_to_mpa(loop.trip_value()),
                 units::pa_to_mpa(loop.trip_limit()), t);
    case Trip::underpressure:
      return fmt("underpressure: p_meas %.4f MPa below the %.4f MPa limit at t = %.3f s", units::pa_to_mpa(loop.trip_value()),
                 units::pa_to_mpa(loop.trip_limit()), t);
    case Trip::watchdog: {
      // What the rig says the reads waited on ("transducer: newest reading 41.0 ms old (limit 4.0
      // ms): ...: ILLEGAL DATA ADDRESS (exception 2)"): the count alone named no cause.
      const std::string detail(loop.trip_detail());
      return fmt("watchdog: %.0f rig reads missed in a row at t = %.3f s", loop.trip_value(), t) +
             (detail.empty() ? "" : ": " + detail);
    }
    case Trip::rig_fault: return fmt("rig fault at t = %.3f s: ", t) + std::string(loop.trip_detail());
    case Trip::overruns:
      return fmt("overruns: %.0f periods in a row ended after their next deadline at t = %.3f s", loop.trip_value(), t);
    case Trip::operator_abort: return "operator abort";
    case Trip::recording: return fmt("recording: telemetry could not be recorded at t = %.3f s", t);
    case Trip::following_error:
      return fmt("following error: the drive's position %+.3f deg from its target, beyond the %.3f deg limit for %.0f ms",
                 units::rad_to_deg(loop.trip_value()), units::rad_to_deg(loop.trip_limit()),
                 loop.safety_config().following_error_s * 1000) +
             fmt(" in a row at t = %.3f s (a frozen encoder, a jammed gear or a drive that stopped following)", t);
    case Trip::none: break;
  }
  return "none";
}

json loop_stats_json(const RunLoop& loop) {
  return {{"periods", loop.snapshot().periods},
          {"overruns", loop.snapshot().overruns},
          {"skipped_deadlines", loop.snapshot().skipped_deadlines},
          {"missed_reads", loop.snapshot().missed_reads},
          {"limited_periods", loop.snapshot().limited_periods},
          {"wake_latency_us", loop.wake_latency().summary().to_json()},
          {"compute_us", loop.compute_time().summary().to_json()},
          {"rig_read_us", loop.rig().read_time().summary().to_json()},
          {"rig_write_us", loop.rig().write_time().summary().to_json()}};
}

json faults_json(const LoopSnapshot& s) {
  json faults = json::array();
  auto until = [](double u) { return std::isfinite(u) ? json(std::round(u * 1e3) / 1e3) : json(nullptr); };
  if (s.flags & kFlagGapOverride) faults.push_back({{"kind", "gap"}, {"gap_deg", units::rad_to_deg(s.gap_override_rad)}});
  if (s.sensor != SensorFault::none) {
    json f = {{"kind", "sensor"}, {"mode", to_string(s.sensor)}, {"until_s", until(s.sensor_until_s)}};
    if (s.sensor == SensorFault::bias) f["bias_kpa"] = s.sensor_value / 1e3;
    if (s.sensor == SensorFault::noise) f["rms_kpa"] = s.sensor_value / 1e3;
    if (s.sensor == SensorFault::stuck) f["held_mpa"] = units::pa_to_mpa(s.sensor_value);
    faults.push_back(f);
  }
  if (s.flags & kFlagDriveFault)
    faults.push_back({{"kind", "drive"}, {"mode", "ignores_commands"}, {"until_s", until(s.drive_until_s)}});
  if (s.flags & kFlagRigFault) faults.push_back({{"kind", "rig"}, {"mode", "silent"}});
  return faults;
}

// After a rig's deactivate(): when the drive could not be switched off, says so everywhere an
// operator looks (the reason, an event, the log): it may still be enabled, with the motor
// attached. True when it could not.
bool say_drive_not_disabled(const Rig& rig, Recorder& rec, std::string& reason) {
  const std::string why = rig.deactivate_failure();
  if (why.empty()) return false;
  const std::string text = "switching the drive off failed (" + why + "): it may still be enabled";
  spdlog::error("{}", text);
  rec.log({{"kind", "drive_not_disabled"}, {"source", "bench"}, {"detail", text}});
  reason += (reason.empty() ? "" : "; ") + text;
  return true;
}

}  // namespace

std::string utc_iso(SysClock::time_point t) {
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(t.time_since_epoch()).count() % 1000;
  char frac[8];
  std::snprintf(frac, sizeof frac, ".%03dZ", static_cast<int>(ms));
  return utc(t, "%Y-%m-%dT%H:%M:%S") + frac;
}

struct CampaignRunner::Active {
  StartRequest req;
  bool simulated = true, programmable_gap = true;
  std::vector<const RunSpec*> runs;
  Clock::time_point started;
  SysClock::time_point started_utc;
  // Guarded by the runner's mutex:
  bool stop = false, abort = false;
  std::string abort_reason;
  // What an operator's abort ends a run or the campaign with.
  std::string abort_text() const { return abort_reason.empty() ? "operator abort" : abort_reason; }
  std::size_t index = 0;
  std::filesystem::path dir;
  const RunLoop* loop = nullptr;
  SpscRing<LoopRequest>* requests = nullptr;
  Rig* rig_in_setup = nullptr;  // while its configure() and activate() run: an abort cancels them
  Recorder* recorder = nullptr;
  RtSetup rt;
  std::int64_t periods_done = 0;  // in finished runs
  // The current run's time while no loop runs: 0 before it starts, where it ended after (its
  // record is still being written), so progress never goes back.
  double run_t_s = 0;
  json finished = json::array();
  std::vector<std::pair<std::string, RunSummary>> summaries;  // of finished runs, for checks against another run
};

CampaignRunner::CampaignRunner(RunnerOptions options) : o_(std::move(options)) {}

CampaignRunner::~CampaignRunner() {
  {
    std::lock_guard lock(mutex_);
    if (active_) {
      active_->abort = true;
      active_->abort_reason = "server shutting down";
      if (active_->requests) active_->requests->try_push({.kind = LoopRequest::Kind::abort});
    }
  }
  if (thread_.joinable()) thread_.join();
}

void CampaignRunner::notice(const json& j) const {
  if (o_.on_notice) o_.on_notice(j);
}

bool CampaignRunner::running() const {
  std::lock_guard lock(mutex_);
  return active_ != nullptr;
}

void CampaignRunner::wait() {
  if (thread_.joinable()) thread_.join();
}

std::string speed_problem(double speed, double period_s) {
  if (!(speed >= kMinSpeed && speed <= kMaxSpeed)) {
    return fmt::format("speed {} is outside {}..{} (loop periods per control period of wall time)", speed, kMinSpeed, kMaxSpeed);
  }
  if (period_s / speed > kMaxWallPeriodS) {
    return fmt::format(
        "speed {} paces a {} ms period at {:.3g} s of wall time; at most {} s (the loop reads an abort once a "
        "period): use a speed of at least {:.3g}",
        speed, period_s * 1e3, period_s / speed, kMaxWallPeriodS, period_s / kMaxWallPeriodS);
  }
  return {};
}

void CampaignRunner::start(StartRequest request) {
  auto a = std::make_shared<Active>();
  std::vector<std::string> names;
  for (const auto& r : request.campaign.runs) names.push_back(r.name);
  for (const auto& want : request.runs) {
    if (std::find(names.begin(), names.end(), want) == names.end()) {
      const std::string hint = cfg::closest(want, names);
      throw BadField("runs", "campaign '" + request.campaign.name + "' has no run '" + want + "'" +
                                 (hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
    }
  }
  if (const std::string why = speed_problem(request.speed, request.campaign.period_s); !why.empty()) throw BadField("speed", why);
  // What the rig can do, as its kind declares it (no rig is made, nothing opened).
  const RigCapabilities& can = kind_of(request.rig).capabilities;
  const bool simulated = can.simulated, programmable_gap = can.programmable_gap;
  if (!simulated && request.speed != 1.0) {
    throw BadField("speed", "speed other than 1 needs a simulated rig ('" + request.rig.name + "' is " + request.rig.kind + ")");
  }
  {
    std::lock_guard lock(mutex_);
    if (active_) throw Conflict("campaign '" + active_->req.campaign.name + "' is running; stop or abort it first");
  }
  {
    // Refused now rather than tripped later: the record of every run must fit.
    const std::size_t run_count = request.runs.empty() ? request.campaign.runs.size() : request.runs.size();
    const double rows = std::ceil(request.campaign.duration_s / request.campaign.period_s) * static_cast<double>(run_count);
    const double need = rows * kBytesPerRow + static_cast<double>(run_count) * 2.0 * kReserveBytes;
    std::error_code ec;
    std::filesystem::create_directories(o_.runs_dir, ec);
    const auto space = std::filesystem::space(o_.runs_dir, ec);
    if (ec) throw InsufficientStorage("cannot use the runs folder " + o_.runs_dir.string() + ": " + ec.message());
    if (static_cast<double>(space.available) < need) {
      throw InsufficientStorage(
          fmt("the runs folder has %.1f MB free; this campaign's record needs about %.1f MB (%.0f telemetry rows)",
              static_cast<double>(space.available) / 1e6, need / 1e6, rows) +
          " in " + o_.runs_dir.string());
    }
  }
  if (thread_.joinable()) thread_.join();  // the previous campaign's thread, already finishing
  std::lock_guard lock(mutex_);
  if (active_) throw Conflict("campaign '" + active_->req.campaign.name + "' is running; stop or abort it first");
  a->req = std::move(request);
  a->simulated = simulated;
  a->programmable_gap = programmable_gap;
  for (const auto& r : a->req.campaign.runs) {
    if (a->req.runs.empty() || std::find(a->req.runs.begin(), a->req.runs.end(), r.name) != a->req.runs.end()) {
      a->runs.push_back(&r);
    }
  }
  a->started = Clock::now();
  a->started_utc = SysClock::now();
  active_ = a;
  thread_ = std::thread([this, a] { run_campaign(a); });
}

void CampaignRunner::stop() {
  std::lock_guard lock(mutex_);
  if (!active_) throw Conflict("no campaign is running");
  active_->stop = true;
  if (active_->recorder) active_->recorder->log({{"kind", "stop_request"}, {"source", "operator"}});
  if (active_->requests) active_->requests->try_push({.kind = LoopRequest::Kind::stop});
}

std::string CampaignRunner::abort(const std::string& reason) {
  std::lock_guard lock(mutex_);
  if (!active_) throw Conflict("no campaign is running");
  const bool first = !active_->abort;
  if (first) {
    active_->abort = true;
    active_->abort_reason = reason;
  }
  if (active_->recorder) {
    json e = {{"kind", "abort_request"}, {"source", "operator"}, {"reason", reason}};
    if (!first) e["ends_with"] = active_->abort_reason;  // an abort was under way: its reason stands
    active_->recorder->log(e);
  }
  if (active_->requests) active_->requests->try_push({.kind = LoopRequest::Kind::abort});
  if (active_->rig_in_setup) active_->rig_in_setup->cancel_setup();
  return active_->abort_reason;
}

void check_injection(const LoopRequest& r) {
  using K = LoopRequest::Kind;
  const auto within = [](double v, double lo, double hi) { return std::isfinite(v) && v >= lo && v <= hi; };
  if (!within(r.duration_s, 0, kMaxInjectionS)) {
    throw BadField("duration_s",
                   fmt::format("'duration_s' {} s is outside 0..{} s (0 = until cleared)", r.duration_s, kMaxInjectionS));
  }
  if (r.kind == K::set_gap && !within(r.value, 0, units::deg_to_rad(kMaxInjectedGapDeg))) {
    throw BadField("gap_deg",
                   fmt::format("'gap_deg' {} deg is outside 0..{} deg", units::rad_to_deg(r.value), kMaxInjectedGapDeg));
  }
  if (r.kind == K::sensor_fault && r.sensor == SensorFault::bias &&
      !within(r.value, -kMaxSensorBiasKpa * units::kPaPerKpa, kMaxSensorBiasKpa * units::kPaPerKpa)) {
    throw BadField("bias_kpa", fmt::format("'bias_kpa' {} kPa is outside -{}..{} kPa", r.value / units::kPaPerKpa,
                                           kMaxSensorBiasKpa, kMaxSensorBiasKpa));
  }
  if (r.kind == K::sensor_fault && r.sensor == SensorFault::noise && !within(r.value, 0, kMaxSensorNoiseKpa * units::kPaPerKpa)) {
    throw BadField("rms_kpa",
                   fmt::format("'rms_kpa' {} kPa RMS is outside 0..{} kPa", r.value / units::kPaPerKpa, kMaxSensorNoiseKpa));
  }
}

void CampaignRunner::inject(const LoopRequest& request) {
  check_injection(request);  // a value no run could take is the request's fault, running or not
  std::lock_guard lock(mutex_);
  if (!active_) throw Conflict("no campaign is running");
  if (!active_->requests) throw Conflict("no run is in its loop right now (between runs); try again");
  using K = LoopRequest::Kind;
  if (!active_->programmable_gap && (request.kind == K::set_gap || request.kind == K::programme_gap)) {
    throw std::invalid_argument("rig '" + active_->req.rig.name + "' is hardware (" + active_->req.rig.kind +
                                "): gap changes need a rig with a simulated valve (sim or hybrid)");
  }
  if (!active_->simulated && request.kind == K::rig_fault) {
    throw std::invalid_argument("rig '" + active_->req.rig.name + "' has hardware (" + active_->req.rig.kind +
                                "): rig faults are faked by the simulated rig only");
  }
  if (!active_->requests->try_push(request)) throw Conflict("the loop has not taken the previous requests yet; try again");
}

void CampaignRunner::run_campaign(std::shared_ptr<Active> a) {
  for (std::size_t i = 0; i < a->runs.size(); ++i) {
    {
      std::lock_guard lock(mutex_);
      if (a->stop || a->abort) break;
      a->index = i;
      a->run_t_s = 0;
    }
    try {
      run_one(*a, i);
    } catch (const std::exception& e) {
      spdlog::error("campaign '{}' run '{}': {}", a->req.campaign.name, a->runs[i]->name, e.what());
      a->finished.push_back({{"run", a->runs[i]->name}, {"outcome", to_string(Outcome::error)}, {"reason", e.what()}});
    }
    if (outcome_from(a->finished.back()["outcome"].get<std::string>()) != Outcome::completed) break;
  }
  json last = {{"campaign", a->req.campaign.name},
               {"source", a->req.source},
               {"rig", a->req.rig.name},
               {"started_utc", utc_iso(a->started_utc)},
               {"finished_utc", utc_iso(SysClock::now())},
               {"runs", a->finished},
               {"outcome", to_string(Outcome::completed)},
               {"reason", nullptr}};
  Outcome worst = Outcome::completed;
  for (const auto& r : a->finished) {
    const Outcome o = outcome_from(r["outcome"].get<std::string>());
    if (o > worst) worst = o, last["outcome"] = r["outcome"], last["reason"] = r["reason"];
  }
  if (a->finished.size() < a->runs.size()) last["runs_skipped"] = a->runs.size() - a->finished.size();
  {
    // A stop or abort that came between runs (or before the first began) ended the campaign
    // without a run to carry it: the campaign says so, not "completed" with runs skipped.
    std::lock_guard lock(mutex_);
    if (worst == Outcome::completed && a->finished.size() < a->runs.size() && (a->abort || a->stop)) {
      last["outcome"] = to_string(a->abort ? Outcome::aborted : Outcome::stopped);
      last["reason"] =
          a->abort ? a->abort_text() : std::string("operator stop before run '") + a->runs[a->finished.size()]->name + "'";
    }
  }
  notice(
      {{"type", "campaign_end"}, {"campaign", a->req.campaign.name}, {"outcome", last["outcome"]}, {"reason", last["reason"]}});
  std::lock_guard lock(mutex_);
  last_ = std::move(last);
  active_.reset();
}

void CampaignRunner::run_one(Active& a, std::size_t index) {
  keep_off_cpu(a.req.rig.loop.cpu);  // this thread only waits, but keeps the loop's CPU to the loop
  const Campaign& c = a.req.campaign;
  const RunSpec& run = *a.runs[index];
  const RigConfig& rc = a.req.rig;
  const auto start_utc = SysClock::now();
  const auto dir = unique_dir(o_.runs_dir / (utc(start_utc, "%Y%m%dT%H%M%SZ") + "_" + c.name + "_" + run.name));
  std::optional<FileLock> run_lock;
  try {
    run_lock.emplace(run_lock_file(dir), /*remove_when_released=*/true);
    // The reserve is taken first: a disk without room for it would not take the run's record.
    const int fd = ::open((dir / ".reserve").c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
    const int rc = fd < 0 ? errno : ::posix_fallocate(fd, 0, static_cast<off_t>(kReserveBytes));
    if (fd >= 0) ::close(fd);
    if (rc != 0) throw InsufficientStorage(std::string("cannot reserve space in ") + dir.string() + ": " + std::strerror(rc));
  } catch (...) {
    run_lock.reset();
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
    throw;
  }
  RunRecord info;
  info.version = o_.version;
  info.host = hostname();
  info.pid = ::getpid();
  info.campaign = c.name;
  info.run = run.name;
  info.run_index = static_cast<std::int64_t>(index);
  info.runs_in_campaign = static_cast<std::int64_t>(a.runs.size());
  info.rig_name = rc.name;
  info.rig_kind = rc.kind;
  info.start_utc = utc_iso(start_utc);
  info.period_s = c.period_s;
  info.duration_s = c.duration_s;
  info.speed = a.req.speed;
  const auto absolute = [](const std::filesystem::path& p) {
    std::error_code ec;
    const auto abs = p.empty() ? p : std::filesystem::absolute(p, ec);
    return (ec ? p : abs).string();
  };
  // Absolute paths: a report or analysis of the run may be made from another folder.
  info.config = {a.req.source, absolute(c.file),       c.yaml_text,      absolute(rc.file),
                 rc.yaml_text, absolute(c.plant_file), c.plant_yaml_text};
  try {
    write_run_record(dir, info);
  } catch (...) {
    run_lock.reset();
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);  // a folder without run.json would be no run at all
    throw;
  }

  std::unique_ptr<Rig> rig = make_rig(rc, o_.can_transport);
  RunVerdicts verdicts(c, run, rig->knows_truth(), o_.on_row);  // outlives the recorder, which feeds it
  Recorder rec(dir,
               {{"source", "hilbench serve"},
                {"campaign", c.name},
                {"run", run.name},
                {"rig", rc.name},
                {"start_utc", utc_iso(start_utc)}},
               static_cast<std::size_t>(rc.loop.ring_rows), verdicts.sink(), std::chrono::milliseconds(100), rig->knows_truth(),
               rc.loop.cpu);
  // The run's snapshot in telemetry.mcap, as run.json keeps it: a recording opened alone says
  // what it was made of.
  rec.metadata("campaign", {{"source", info.config.campaign_source},
                            {"file", info.config.campaign_file},
                            {"yaml", info.config.campaign_yaml},
                            {"name", c.name},
                            {"run", run.name}});
  rec.metadata("plant", {{"file", info.config.plant_file}, {"yaml", info.config.plant_yaml}});
  rec.metadata("rig", {{"file", info.config.rig_file}, {"yaml", info.config.rig_yaml}, {"name", rc.name}, {"kind", rc.kind}});
  rec.log({{"kind", "run_start"},
           {"source", "bench"},
           {"campaign", c.name},
           {"run", run.name},
           {"rig", rc.name},
           {"speed", a.req.speed}});
  {
    std::lock_guard lock(mutex_);
    a.dir = dir;
    a.recorder = &rec;
  }

  SpscRing<LoopRequest> requests(64);
  std::unique_ptr<RunLoop> loop;
  Outcome outcome = Outcome::error;
  std::string reason;
  {
    // From here an abort cuts the setup short; one that came before is passed on at once.
    std::lock_guard lock(mutex_);
    a.rig_in_setup = rig.get();
    if (a.abort) rig->cancel_setup();
  }
  try {
    Schedule::Cursor rc0, gc0;
    rig->configure({&c, c.period_s, c.reference_pa.at(0.0, rc0), c.gap_rad.at(0.0, gc0)});
    rig->activate();
    const auto wall = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(c.period_s / a.req.speed));
    loop = std::make_unique<RunLoop>(c, run, *rig, rc.safety, rc.loop, wall, rec.telemetry(), rec.events(), requests);
    loop->watch_recording(&rec.failed());
    loop->begin(Clock::now());
  } catch (const std::exception& e) {
    outcome = Outcome::error;
    reason = std::string("rig '") + rc.name + "' setup: " + e.what();
    rec.log({{"kind", "rig_error"}, {"source", "bench"}, {"detail", reason}});
    {
      std::lock_guard lock(mutex_);
      if (a.abort) {  // the setup ended because of it (or would have been cut short by it)
        outcome = Outcome::aborted;
        reason = a.abort_text() + " during the setup of rig '" + rc.name + "' (" + e.what() + ")";
      }
    }
    rig->deactivate();
    say_drive_not_disabled(*rig, rec, reason);
    loop.reset();
  }
  {
    std::lock_guard lock(mutex_);
    a.rig_in_setup = nullptr;
  }

  RtSetup rt;
  std::optional<CpuLatencyRequest> cpu_latency;
  if (loop && rc.loop.cpu_dma_latency_us >= 0) {
    cpu_latency.emplace(rc.loop.cpu_dma_latency_us);
    if (!cpu_latency->warning().empty()) spdlog::warn("{}", cpu_latency->warning());
  }
  if (loop) {
    std::binary_semaphore go(0);
    std::thread t([&] {
      go.acquire();
      prefault_stack();
      run_paced(*loop, Clock::now());
    });
    rt = make_realtime(t, rc.loop.priority, rc.loop.cpu);
    if (!rt.warning.empty()) spdlog::warn("loop thread: {}", rt.warning);
    rec.log({{"kind", "loop_start"},
             {"source", "bench"},
             {"sched", rt.describe()},
             {"warning", rt.warning},
             {"mlock_warning", o_.mlock_warning},
             {"cpu_dma_latency",
              cpu_latency ? (cpu_latency->warning().empty() ? json(rc.loop.cpu_dma_latency_us) : json(cpu_latency->warning()))
                          : json(nullptr)}});
    {
      std::lock_guard lock(mutex_);
      a.loop = loop.get();
      a.requests = &requests;
      a.rt = rt;
      if (a.abort) requests.try_push({.kind = LoopRequest::Kind::abort});
      if (a.stop) requests.try_push({.kind = LoopRequest::Kind::stop});
    }
    notice({{"type", "run_start"},
            {"t_s", 0.0},  // the new run's clock (the stream's last row is the previous run's end)
            {"campaign", c.name},
            {"run", run.name},
            {"dir", dir.filename().string()},
            {"period_s", c.period_s},
            {"duration_s", c.duration_s}});
    go.release();
    t.join();
    std::lock_guard lock(mutex_);
    switch (loop->end()) {
      case LoopEnd::completed: outcome = Outcome::completed; break;
      case LoopEnd::stopped: outcome = Outcome::stopped, reason = "operator stop"; break;
      case LoopEnd::tripped:
      case LoopEnd::running:
        outcome = Outcome::aborted;
        reason = loop->trip() == Trip::operator_abort ? a.abort_text() : describe_trip(*loop);
        break;
    }
    a.periods_done += loop->periods_run();
  }
  json rig_health = nullptr;  // how the rig's devices ended the run (before they are switched off)
  if (loop) {
    const RigHealth h = rig->health();
    rig_health = {{"connected", h.connected},
                  {"fault", h.fault},
                  {"reads", h.reads},
                  {"stale_reads", h.stale_reads},
                  {"fault_reads", h.fault_reads},
                  {"reconnects", h.reconnects},
                  {"reconnects_by_device", {{"drive", h.drive_reconnects}, {"transducer", h.transducer_reconnects}}},
                  {"last_error", std::string(h.last_error_text())}};
    rig->deactivate();
    if (say_drive_not_disabled(*rig, rec, reason)) {
      rig_health["disable_error"] = rig->deactivate_failure();
      if (outcome == Outcome::completed) outcome = Outcome::error;  // the run is over, the drive may not be
    }
  }
  cpu_latency.reset();

  const std::string write_error = rec.finish();
  {
    std::lock_guard lock(mutex_);
    if (loop) a.run_t_s = run_time_s(loop->snapshot(), c);
    a.loop = nullptr;
    a.requests = nullptr;
    a.recorder = nullptr;
  }
  if (loop && loop->trip() == Trip::recording) {
    reason += write_error.empty() ? fmt(": the telemetry ring was full (%.0f rows lost)", static_cast<double>(loop->rows_lost()))
                                  : ": " + write_error;
  } else if (!write_error.empty() && outcome == Outcome::completed) {
    outcome = Outcome::error, reason = "telemetry: " + write_error;
  }
  const std::uint64_t rows_not_recorded = rec.rows_unwritten() + (loop ? loop->rows_lost() : 0);
  if (rows_not_recorded > 0 && !reason.empty()) reason += fmt("; %.0f rows not recorded", static_cast<double>(rows_not_recorded));
  const auto stop_utc = SysClock::now();
  info.stop_utc = utc_iso(stop_utc);
  info.outcome = outcome;
  if (!reason.empty()) info.reason = reason;
  info.ended = true;
  info.rig_health = rig_health;
  if (loop) {
    if (loop->trip() != Trip::none) {
      info.trip = RunRecord::Trip{std::string(to_string(loop->trip())), loop->trip_t_s(),
                                  std::isfinite(loop->trip_value()) ? std::optional(loop->trip_value()) : std::nullopt,
                                  std::isfinite(loop->trip_limit()) ? std::optional(loop->trip_limit()) : std::nullopt};
    }
    info.periods_run = loop->periods_run();
    json stats = loop_stats_json(*loop);
    stats["sched"] = rt.describe();
    stats["rt_warning"] = rt.warning;
    stats["memory_locked"] = o_.mlock_warning.empty();
    stats["cpu_dma_latency_us"] = rc.loop.cpu_dma_latency_us;
    stats["overrun_policy"] = rc.loop.overrun_policy == OverrunPolicy::abort ? "abort" : "count";
    stats["wall_period_us"] = std::chrono::duration<double, std::micro>(loop->wall_period()).count();
    info.loop = stats;
  }
  RunRecord::Telemetry tel;
  tel.rows_written = rec.rows_written();
  tel.rows_lost = loop ? loop->rows_lost() : 0;
  tel.rows_unwritten = rec.rows_unwritten();
  tel.events_lost = loop ? loop->events_lost() : 0;
  tel.events_unwritten = rec.events_unwritten();
  tel.ring_rows = rec.telemetry().capacity();
  tel.write_error_known = true;
  if (!write_error.empty()) tel.write_error = write_error;
  info.telemetry = tel;
  {
    const auto other = [&a](const std::string& name) -> const RunSummary* {
      for (const auto& [n, summary] : a.summaries)
        if (n == name) return &summary;
      return nullptr;
    };
    const bool pressure_trip = loop && (loop->trip() == Trip::overpressure || loop->trip() == Trip::underpressure);
    info.checks = verdicts.finish(pressure_trip, other);
    if (!info.checks.is_null()) a.summaries.emplace_back(run.name, verdicts.summary());
  }
  {
    std::error_code ec;
    std::filesystem::remove(dir / ".reserve", ec);  // its room is for this last write
  }
  try {
    write_run_record(dir, info);
  } catch (const std::exception& e) {
    spdlog::error("run {}: cannot write the final run.json ({}); outcome {}: {}", dir.string(), e.what(), to_string(outcome),
                  reason);
    // run.json still says "running": the event log, where it still takes a line, keeps the end,
    // so a later server restores it instead of calling the run interrupted by a crash.
    rec.log({{"kind", std::string(kFinalRecordUnwritten)},
             {"source", "bench"},
             {"outcome", to_string(outcome)},
             {"reason", info.reason ? json(*info.reason) : json(nullptr)},
             {"error", e.what()}});
    std::lock_guard lock(unrecorded_mutex_);
    unrecorded_[dir.filename().string()] = info;
  }
  // run.json as it now stands (final, or still "running" where it could not be written) goes
  // into telemetry.mcap, which is then closed with its summary.
  std::string run_json;
  try {
    run_json = read_text_file(dir / "run.json", "run.json");
  } catch (const std::exception& e) {
    spdlog::warn("run {}: telemetry.mcap is closed without run.json ({})", dir.string(), e.what());
  }
  if (const std::string e = rec.seal(run_json); !e.empty()) spdlog::warn("run {}: telemetry.mcap: {}", dir.string(), e);
  run_lock.reset();
  const json reason_or_null = info.reason ? json(*info.reason) : json(nullptr);
  json summary = {
      {"run", run.name}, {"dir", dir.filename().string()}, {"outcome", to_string(outcome)}, {"reason", reason_or_null}};
  json end = {{"type", "run_end"},
              {"campaign", c.name},
              {"run", run.name},
              {"dir", dir.filename().string()},
              {"outcome", to_string(outcome)},
              {"reason", reason_or_null},
              // the interlock that ended it, or "operator abort" (the console latches SAFE or TRIPPED on it)
              {"trip", info.trip ? json(info.trip->reason) : json(nullptr)}};
  if (!info.checks.is_null()) summary["checks"] = end["checks"] = info.checks;
  notice(end);
  std::lock_guard lock(mutex_);
  a.finished.push_back(summary);
}

json CampaignRunner::status() const {
  std::lock_guard lock(mutex_);
  json s;
  s["last"] = last_.is_null() ? json(nullptr) : last_;
  if (!active_) {
    s["state"] = "idle";
    return s;
  }
  const Active& a = *active_;
  const Campaign& c = a.req.campaign;
  s["campaign"] = c.name;
  s["source"] = a.req.source;
  s["rig"] = a.req.rig.name;
  s["speed"] = a.req.speed;
  s["run"] = a.runs[a.index]->name;
  s["run_index"] = a.index;
  s["runs"] = json::array();
  for (const auto* r : a.runs) s["runs"].push_back(r->name);
  s["runs_total"] = a.runs.size();
  s["run_dir"] = a.dir.filename().string();
  s["operator_link"] = {{"required", a.req.rig.require_operator}, {"timeout_s", a.req.rig.operator_timeout_s}};
  const double per_run = c.duration_s;
  double t = a.run_t_s;
  if (a.loop) {
    const LoopSnapshot snap = a.loop->snapshot();
    t = run_time_s(snap, c);
    s["state"] = (snap.flags & kFlagSafeState) ? "safe" : "running";
    json loop = loop_stats_json(*a.loop);
    loop["sched"] = a.rt.describe();
    loop["rt_warning"] = a.rt.warning;
    loop["memory_locked"] = o_.mlock_warning.empty();
    s["loop"] = loop;
    s["faults"] = faults_json(snap);
    s["safety"] = {{"safe_state", (snap.flags & kFlagSafeState) != 0},
                   {"trip", snap.trip == Trip::none ? json(nullptr) : json(to_string(snap.trip))}};
    if (snap.trip == Trip::operator_abort) s["safety"]["reason"] = a.abort_text();
    s["telemetry"] = {
        {"rows_lost", snap.rows_lost},
        {"rows_unwritten", a.recorder ? a.recorder->rows_unwritten() : 0},
        {"rows_written", a.recorder ? a.recorder->rows_written() : 0},
        {"write_error", a.recorder && a.recorder->failed().load() ? json("the disk refused telemetry") : json(nullptr)},
        {"events_lost", snap.events_lost},
        // Rows the loop has handed over that the recorder has not taken yet (approximate: both
        // sides move while it is read); at ring_capacity the next rows are lost.
        {"ring_fill", a.recorder ? a.recorder->telemetry().size() : 0},
        {"ring_capacity", a.recorder ? a.recorder->telemetry().capacity() : 0}};
    s["now"] = {{"t_s", snap.t_s},
                {"p_meas_mpa", std::isfinite(snap.p_meas_pa) ? json(units::pa_to_mpa(snap.p_meas_pa)) : json(nullptr)},
                {"p_ref_mpa", units::pa_to_mpa(snap.p_ref_pa)},
                {"theta_cmd_deg", units::rad_to_deg(snap.theta_cmd_rad)},
                {"gap_true_deg", std::isfinite(snap.gap_rad) ? json(units::rad_to_deg(snap.gap_rad)) : json(nullptr)}};
  } else {
    s["state"] = "starting";
    s["faults"] = json::array();
  }
  const double total = per_run * static_cast<double>(a.runs.size());
  const double done = per_run * static_cast<double>(a.index) + t;
  const double elapsed = std::chrono::duration<double>(Clock::now() - a.started).count();
  s["progress"] = {{"t_s", t},
                   {"duration_s", per_run},
                   {"fraction", total > 0 ? done / total : 0},
                   {"elapsed_s", elapsed},
                   {"remaining_s", (total - done) / a.req.speed}};
  return s;
}

std::optional<CampaignRunner::UnrecordedEnd> CampaignRunner::unrecorded_end(const std::string& run_dir_name) {
  std::lock_guard lock(unrecorded_mutex_);
  const auto it = unrecorded_.find(run_dir_name);
  if (it == unrecorded_.end()) return std::nullopt;
  UnrecordedEnd end{it->second, false};
  try {
    write_run_record(o_.runs_dir / run_dir_name, end.record);
    spdlog::info("run {}: the final run.json is written now", run_dir_name);
    unrecorded_.erase(it);
    end.written = true;
  } catch (const std::exception& e) {
    end.record.reason = (end.record.reason ? *end.record.reason + "; " : std::string()) +
                        "its final run.json could not be written (" + e.what() +
                        "), so the file still says running; this server shows the end it keeps, and a server restart "
                        "restores it from events.jsonl";
  }
  return end;
}

}  // namespace hil::bench
