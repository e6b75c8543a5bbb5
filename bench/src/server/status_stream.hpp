// The bench's state pushed to the console on its telemetry WebSocket, so that a change shows at
// once instead of at the next poll (the sim rig holds its safe state 200 ms; a console polling
// once a second went from RUNNING to IDLE and never showed SAFE). A thread reads the runner's
// status ten times a second and publishes {"type": "status", ...} (status_message) on every change
// of state, run, reason or a check's live verdict, and at least every kHeartbeat otherwise: that heartbeat is how a page
// knows its link is alive while nothing runs. The same thread applies the operator link's rule
// (operator_link.hpp). Never on the real-time path: it only reads the runner's snapshot.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>

#include <nlohmann/json.hpp>

#include "hil/bench/server/runner.hpp"
#include "operator_link.hpp"

namespace hil::bench {

// The stream's message for a runner status (CampaignRunner::status()): state is one of idle,
// starting, running, safe (an operator's abort, or the operator link lost) or tripped (an
// interlock), with the reason in words when safe or tripped; the run, its time and duration; the
// operator link's requirement and how long no client was heard (silent_s, -1 when unknown); the
// running run's checks as they stand ("checks", RunVerdicts::live) when its campaign has some.
nlohmann::json status_message(const nlohmann::json& status, std::uint64_t seq, double silent_s);

class StatusStream {
 public:
  static constexpr std::chrono::milliseconds kPoll{100}, kHeartbeat{500};
  // publish: the hub's publish_status (plain JSON clients only; never blocks).
  StatusStream(CampaignRunner& runner, OperatorLink& link, std::function<void(const nlohmann::json&)> publish);
  ~StatusStream();  // stop()
  StatusStream(const StatusStream&) = delete;
  StatusStream& operator=(const StatusStream&) = delete;
  void stop();

 private:
  void loop();
  CampaignRunner& runner_;
  OperatorLink& link_;
  std::function<void(const nlohmann::json&)> publish_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace hil::bench
