// The operator link a run may require (`require_operator: true` in its rig file): when no console
// or `ctl` client has been heard for the rig's operator_timeout_s while such a run runs, the run
// goes to its safe state with the reason "operator link lost". Heard means any authorised request
// (the console asks for /api/status every second, `ctl watch` polls it too). The decision is made
// here, off the real-time path, by the status stream's thread, and handed to the loop the way an
// operator's abort is (CampaignRunner::abort). Off by default: CI and sweeps run unattended.
#pragma once

#include <atomic>
#include <chrono>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

namespace hil::bench {

inline constexpr std::string_view kOperatorLinkLost = "operator link lost";

class OperatorLink {
 public:
  using Clock = std::chrono::steady_clock;
  // Any thread, any time: a client was heard now.
  void heard() noexcept { last_heard_ns_.store(Clock::now().time_since_epoch().count(), std::memory_order_relaxed); }
  // Seconds since a client was last heard (a large number when never).
  double silent_s(Clock::time_point now) const noexcept;
  // Given the runner's status (CampaignRunner::status(), with its "operator_link" and "run_dir"),
  // the abort reason when the running campaign requires an operator and none was heard for its
  // timeout, counted from the later of the last word heard and the moment this run was first
  // seen. One caller thread (the status stream's).
  std::optional<std::string> lost(const nlohmann::json& status, Clock::time_point now);

 private:
  std::atomic<Clock::rep> last_heard_ns_{0};
  std::string run_dir_;         // the run last seen
  Clock::time_point run_seen_;  // when it was first seen
  bool said_ = false;           // lost() said so for this run: once is enough
};

}  // namespace hil::bench
