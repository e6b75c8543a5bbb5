#include "status_stream.hpp"

#include <spdlog/spdlog.h>

#include "hil/bench/rt/safety.hpp"

namespace hil::bench {

using nlohmann::json;

namespace {
std::string verdicts_key(const json& m) {
  std::string key;
  if (!m.contains("checks")) return key;
  for (const json& r : m["checks"].value("results", json::array())) key += r.value("verdict", "") + ",";
  return key;
}
}  // namespace

json status_message(const json& s, std::uint64_t seq, double silent_s) {
  std::string state = s.value("state", "idle");
  json reason = nullptr;
  if (state == "safe") {
    const json& safety = s.contains("safety") ? s["safety"] : json::object();
    const std::string trip = safety.contains("trip") && safety["trip"].is_string() ? safety["trip"].get<std::string>() : "";
    if (safety.contains("reason") && safety["reason"].is_string()) reason = safety["reason"];
    // An operator's abort (or the operator link's) is a commanded safe state; anything else an
    // interlock tripped.
    if (!trip.empty() && trip != to_string(Trip::operator_abort)) {
      state = "tripped";
      if (reason.is_null()) reason = "interlock: " + trip;
    }
  }
  json m = {{"type", "status"}, {"seq", seq}, {"state", state}, {"reason", reason}};
  for (const char* key : {"campaign", "campaign_started_utc", "run", "runs", "rig", "run_dir", "run_index", "runs_total"})
    if (s.contains(key)) m[key] = s[key];
  if (s.contains("progress")) {
    const json& p = s["progress"];
    m["run_t_s"] = p.value("t_s", 0.0);
    m["duration_s"] = p.value("duration_s", 0.0);
    m["fraction"] = p.value("fraction", 0.0);
  }
  if (s.contains("operator_link")) m["operator_link"] = s["operator_link"];
  // The running run's checks as they stand (run_verdicts.hpp, live()); the final ones come in run_end.
  if (s.contains("checks") && s["checks"].is_object()) m["checks"] = s["checks"];
  m["silent_s"] = silent_s < 1e8 ? json(silent_s) : json(-1);
  if (state == "idle" && s.contains("last") && s["last"].is_object()) {
    const json& last = s["last"];
    m["last"] = {{"campaign", last.value("campaign", "")},
                 {"started_utc", last.value("started_utc", "")},
                 {"outcome", last.value("outcome", "")},
                 {"reason", last.contains("reason") ? last["reason"] : json(nullptr)}};
  }
  // What became of the last run (a crash's restart included): the console's header says it.
  if (s.contains("last_run")) m["last_run"] = s["last_run"];
  return m;
}

StatusStream::StatusStream(CampaignRunner& runner, OperatorLink& link, std::function<void(const json&)> publish)
    : runner_(runner), link_(link), publish_(std::move(publish)), thread_([this] { loop(); }) {}

StatusStream::~StatusStream() { stop(); }

void StatusStream::stop() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void StatusStream::loop() {
  std::uint64_t seq = 0;
  std::string last_key;
  auto last_sent = std::chrono::steady_clock::time_point{};
  std::unique_lock lock(mutex_);
  while (!stop_) {
    lock.unlock();
    try {
      const json status = runner_.status();
      const auto now = std::chrono::steady_clock::now();
      if (const auto why = link_.lost(status, now)) {
        spdlog::warn("{}: the run goes to its safe state", *why);
        try {
          runner_.abort(*why);
        } catch (const Conflict&) {  // it ended meanwhile
        }
      }
      const json m = status_message(status, seq, link_.silent_s(now));
      // A check's live verdict changing (a failure, a window closed) is pushed at once, as a
      // change of state is; its value moving is not (the heartbeat carries it).
      const std::string key =
          m.value("state", "") + "|" + m.value("run_dir", "") + "|" + m["reason"].dump() + "|" + verdicts_key(m);
      if (key != last_key || now - last_sent >= kHeartbeat) {
        json out = m;
        out["seq"] = ++seq;
        publish_(out);
        last_key = key;
        last_sent = now;
      }
    } catch (const std::exception& e) {
      spdlog::error("status stream: {}", e.what());
    }
    lock.lock();
    cv_.wait_for(lock, kPoll, [this] { return stop_; });
  }
}

}  // namespace hil::bench
