#include "operator_link.hpp"

#include <algorithm>
#include <cstdio>

namespace hil::bench {

double OperatorLink::silent_s(Clock::time_point now) const noexcept {
  const Clock::rep ns = last_heard_ns_.load(std::memory_order_relaxed);
  if (ns == 0) return 1e9;
  return std::chrono::duration<double>(now - Clock::time_point(Clock::duration(ns))).count();
}

std::optional<std::string> OperatorLink::lost(const nlohmann::json& status, Clock::time_point now) {
  const std::string state = status.value("state", "idle");
  if (state == "idle") {
    run_dir_.clear();
    return std::nullopt;
  }
  const std::string dir = status.value("run_dir", "");
  if (dir != run_dir_) run_dir_ = dir, run_seen_ = now, said_ = false;
  const auto link = status.find("operator_link");
  if (link == status.end() || !link->is_object() || !link->value("required", false)) return std::nullopt;
  if (state != "running" || said_) return std::nullopt;  // starting (the rig's setup), or already safe
  const double timeout_s = link->value("timeout_s", 5.0);
  const double since_run_s = std::chrono::duration<double>(now - run_seen_).count();
  const double silent = std::min(silent_s(now), since_run_s);
  if (silent < timeout_s) return std::nullopt;
  said_ = true;
  char text[200];
  std::snprintf(text, sizeof text, "%s: no console or ctl client heard for %.1f s (require_operator, operator_timeout_s %.1f)",
                std::string(kOperatorLinkLost).c_str(), silent, timeout_s);
  return std::string(text);
}

}  // namespace hil::bench
