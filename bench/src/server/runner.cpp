#include "hil/bench/server/runner.hpp"

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <optional>

#include <spdlog/spdlog.h>

#include "hil/bench/rt/recorder.hpp"
#include "hil/bench/rt/rig_registry.hpp"
#include "hil/bench/rt/rt_thread.hpp"
#include "hil/bench/rt/run_folder.hpp"
#include "hil/bench/rt/run_session.hpp"
#include "hil/config.hpp"
#include "hil/file_lock.hpp"
#include "hil/json_file.hpp"
#include "hil/line_file.hpp"
#include "hil/text_file.hpp"
#include "hil/units.hpp"
#include "run_verdicts.hpp"

namespace hil::bench {
namespace {

using nlohmann::json;
using SysClock = std::chrono::system_clock;

// How far a run is, by its loop's last period: the end of that period (none yet: 0).
double run_time_s(const LoopSnapshot& snap, const Campaign& c) {
  return snap.periods == 0 ? 0 : std::min(snap.t_s + c.period_s, c.duration_s);
}

std::string hostname() {
  char buf[256] = {};
  gethostname(buf, sizeof buf - 1);
  return buf;
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

}  // namespace

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
  const RunVerdicts* verdicts = nullptr;  // the run's checks, live in the status while it goes on
  RtSetup rt;
  std::int64_t periods_done = 0;  // in finished runs
  // The current run's time while no loop runs: 0 before it starts, where it ended after (its
  // record is still being written), so progress never goes back.
  double run_t_s = 0;
  json finished = json::array();
  std::vector<std::pair<std::string, RunSummary>> summaries;  // of finished runs, for checks against another run
};

CampaignRunner::CampaignRunner(RunnerOptions options) : o_(std::move(options)), last_run_(o_.last_run) {}

LastRun LastRun::of(const std::string& dir, const RunRecord& r) {
  return {dir,
          r.campaign,
          r.run,
          r.start_utc,
          r.stop_utc.value_or(""),
          r.outcome,
          r.reason,
          r.trip ? std::optional(r.trip->reason) : std::nullopt};
}

json LastRun::to_json() const {
  return {{"dir", dir},
          {"campaign", campaign},
          {"run", run},
          {"start_utc", start_utc},
          {"stop_utc", stop_utc},
          {"outcome", to_string(outcome)},
          {"reason", reason ? json(*reason) : json(nullptr)},
          {"trip", trip ? json(*trip) : json(nullptr)}};
}

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
    check_room_for_runs(o_.runs_dir, std::ceil(request.campaign.duration_s / request.campaign.period_s), run_count);
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
  if (a->finished.size() < a->runs.size()) {
    last["runs_skipped"] = a->runs.size() - a->finished.size();
    json names = json::array();  // by name: a JUnit verdict lists each as an error
    for (std::size_t i = a->finished.size(); i < a->runs.size(); ++i) names.push_back(a->runs[i]->name);
    last["runs_not_run"] = std::move(names);
  }
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
  const auto started = Clock::now();
  RunRecord info;
  info.version = o_.version;
  info.host = hostname();
  info.pid = ::getpid();
  info.recorded_by = o_.recorded_by;
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
  RunFolder folder(o_.runs_dir, start_utc, c.name, run.name, info);
  const std::filesystem::path& dir = folder.dir();

  std::unique_ptr<Rig> rig = make_rig(rc, o_.can_transport);
  RunVerdicts verdicts(c, run, rig->knows_truth(), o_.on_row);  // outlives the recorder, which feeds it
  Recorder rec(
      dir,
      {{"source", o_.recorded_by}, {"campaign", c.name}, {"run", run.name}, {"rig", rc.name}, {"start_utc", utc_iso(start_utc)}},
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
    a.verdicts = &verdicts;
  }

  // The rig's lifecycle and the loop (rt/run_session.hpp); the runner hears it to keep its status
  // and to pass the operator's requests on.
  RunSession session(*rig, rc, c, run, a.req.speed, rec, o_.mlock_warning);
  RunSessionHooks hooks;
  hooks.in_setup = [this, &a](Rig* r) {
    std::lock_guard lock(mutex_);
    a.rig_in_setup = r;
    if (r != nullptr && a.abort) r->cancel_setup();
  };
  hooks.abort_reason = [this, &a]() -> std::optional<std::string> {
    std::lock_guard lock(mutex_);
    return a.abort ? std::optional(a.abort_text()) : std::nullopt;
  };
  hooks.loop_ready = [this, &a, &c, &run, &dir](const RunLoop& loop, SpscRing<LoopRequest>& requests, const RtSetup& rt) {
    {
      std::lock_guard lock(mutex_);
      a.loop = &loop;
      a.requests = &requests;
      a.rt = rt;
      if (a.abort) requests.try_push({.kind = LoopRequest::Kind::abort});
      if (a.stop) requests.try_push({.kind = LoopRequest::Kind::stop});
    }
    notice({{"type", "run_start"},
            {"t_s", 0.0},  // the new run's clock (the stream's last row is the previous run's end)
            {"campaign", c.name},
            {"campaign_started_utc", utc_iso(a.started_utc)},
            {"run", run.name},
            {"dir", dir.filename().string()},
            {"period_s", c.period_s},
            {"duration_s", c.duration_s}});
  };
  session.run(hooks);
  const RunLoop* loop = session.loop();
  {
    std::lock_guard lock(mutex_);
    if (loop) {
      a.periods_done += loop->periods_run();
      a.run_t_s = run_time_s(loop->snapshot(), c);
    }
    a.loop = nullptr;
    a.requests = nullptr;
    a.recorder = nullptr;
    a.verdicts = nullptr;
  }
  const Outcome outcome = session.outcome();
  info.stop_utc = utc_iso(SysClock::now());
  session.record_end(info);
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
  // The end in events.jsonl too: the event log alone tells how the run ended.
  rec.log({{"kind", "run_end"},
           {"source", "bench"},
           {"outcome", to_string(outcome)},
           {"reason", info.reason ? json(*info.reason) : json(nullptr)},
           {"trip", info.trip ? json(info.trip->reason) : json(nullptr)},
           {"rows_written", info.telemetry && info.telemetry->rows_written ? json(*info.telemetry->rows_written) : json(nullptr)},
           {"checks_failed", info.checks.is_object() ? info.checks.value("failed", json(nullptr)) : json(nullptr)}});
  try {
    folder.write_final(info);
  } catch (const std::exception& e) {
    spdlog::error("run {}: cannot write the final run.json ({}); outcome {}: {}", dir.string(), e.what(), to_string(outcome),
                  session.reason());
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
  folder.release();
  const json reason_or_null = info.reason ? json(*info.reason) : json(nullptr);
  json summary = {{"run", run.name},
                  {"dir", dir.filename().string()},
                  {"outcome", to_string(outcome)},
                  {"reason", reason_or_null},
                  {"wall_s", std::chrono::duration<double>(Clock::now() - started).count()}};
  json end = {{"type", "run_end"},
              {"campaign", c.name},
              {"campaign_started_utc", utc_iso(a.started_utc)},
              {"run", run.name},
              {"dir", dir.filename().string()},
              {"outcome", to_string(outcome)},
              {"reason", reason_or_null},
              // the interlock that ended it, or "operator abort" (the console latches SAFE or TRIPPED on it)
              {"trip", info.trip ? json(info.trip->reason) : json(nullptr)}};
  if (!info.checks.is_null()) summary["checks"] = end["checks"] = info.checks;
  {
    std::lock_guard lock(mutex_);
    last_run_ = LastRun::of(dir.filename().string(), info);
  }
  notice(end);
  std::lock_guard lock(mutex_);
  a.finished.push_back(summary);
}

json CampaignRunner::status() const {
  std::lock_guard lock(mutex_);
  json s;
  s["last"] = last_.is_null() ? json(nullptr) : last_;
  s["last_run"] = last_run_ ? last_run_->to_json() : json(nullptr);
  if (!active_) {
    s["state"] = "idle";
    return s;
  }
  const Active& a = *active_;
  const Campaign& c = a.req.campaign;
  s["campaign"] = c.name;
  s["campaign_started_utc"] = utc_iso(a.started_utc);  // which campaign of that name: a console's panels belong to one
  s["source"] = a.req.source;
  s["rig"] = a.req.rig.name;
  s["speed"] = a.req.speed;
  s["run"] = a.runs[a.index]->name;
  s["run_index"] = a.index;
  s["runs"] = json::array();
  for (const auto* r : a.runs) s["runs"].push_back(r->name);
  s["runs_total"] = a.runs.size();
  s["run_dir"] = a.dir.filename().string();
  if (a.verdicts) {
    if (json live = a.verdicts->live(); !live.is_null()) s["checks"] = std::move(live);
  }
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
