// Candidate effect: a pure delay between the command and the drive acting on it (bus, drive
// cycle). Keeps the recent command history in a fixed ring inside the state vector and reads it
// back with linear interpolation, so the delay is continuous in its parameter (fittable) and
// steps need not be uniform.
#include <algorithm>
#include <cmath>

#include "hil/plant/fit_prior.hpp"
#include "hil/plant/registry.hpp"

namespace hil::plant {

class TransportDelay final : public ScalarEffect<TransportDelay> {
 public:
  static constexpr std::string_view kKind = "transport_delay";
  static constexpr Stage kStage = Stage::command;
  static constexpr ParamSpec kSpecs[] = {
      {"delay_s", 0, 1.0, false, false, kNaN, "delay between command and drive"},
  };
  using ScalarEffect::ScalarEffect;

  // How diagnose finds it (fit_prior.hpp): the cost is flat at 0, so LM starts from the best of a
  // few delays.
  static FitPrior fit_prior(const FitEvidence& ev) {
    const double v = ev.model_value("transport_delay", "delay_s");
    std::vector<double> starts = {0.005, 0.02, 0.05, 0.1};
    if (std::isfinite(v)) starts.insert(starts.begin(), v);
    FitPrior p;
    p.description = "a pure delay between the command and the drive acting on it";
    p.command_side = true;
    p.params = {{.key = "delay_s", .neutral = 0, .lo = 0, .hi = 0.5, .scale = 0.005, .starts = starts, .sample_step = true}};
    p.variants = {{"delay", {"delay_s"}}};
    return p;
  }

  // Layout: [head, count, t0, cmd0, t1, cmd1, ...]; head is the next slot to write.
  static constexpr std::size_t kSlots = 4096;  // 1 s at 4 kHz
  std::size_t state_size() const noexcept override { return 2 + 2 * kSlots; }

  void settle(std::span<double> x, Signals& s) const override {
    x[0] = 1;
    x[1] = 1;
    x[2] = s.t_s;  // the command has been constant up to t0; older queries return it
    x[3] = s.theta_cmd_rad;
  }
  void step(std::span<double> x, Signals& s, double dt_s, Rng&) const noexcept override {
    const double t_start = s.t_s - dt_s;  // the command applies from the start of the step
    auto head = static_cast<std::size_t>(x[0]);
    auto count = static_cast<std::size_t>(x[1]);
    x[2 + 2 * head] = t_start;
    x[3 + 2 * head] = s.theta_cmd_rad;
    head = (head + 1) % kSlots;
    count = std::min(count + 1, kSlots);
    x[0] = static_cast<double>(head);
    x[1] = static_cast<double>(count);
    // Sample `age` steps back from the newest (age 0); times fall as age grows.
    auto slot = [&](std::size_t age) { return (head + kSlots - 1 - age) % kSlots; };
    auto time = [&](std::size_t age) { return x[2 + 2 * slot(age)]; };
    auto cmd = [&](std::size_t age) { return x[3 + 2 * slot(age)]; };
    const double t_want = t_start - value(0);
    if (time(count - 1) > t_want) {  // history shorter than the delay
      s.theta_cmd_rad = cmd(count - 1);
      return;
    }
    // Binary search for the youngest sample at or before t_want.
    std::size_t lo = 0, hi = count - 1;  // time(hi) <= t_want holds
    while (lo < hi) {
      const std::size_t mid = (lo + hi) / 2;
      if (time(mid) <= t_want)
        hi = mid;
      else
        lo = mid + 1;
    }
    if (lo == 0) {
      s.theta_cmd_rad = cmd(0);
      return;
    }
    const double t_old = time(lo), t_new = time(lo - 1);
    const double f = t_new > t_old ? (t_want - t_old) / (t_new - t_old) : 1.0;
    s.theta_cmd_rad = cmd(lo) + std::clamp(f, 0.0, 1.0) * (cmd(lo - 1) - cmd(lo));
  }
};

HIL_REGISTER_EFFECT(TransportDelay, "pure delay between command and drive")
HIL_REGISTER_FIT_PRIOR(TransportDelay)

}  // namespace hil::plant
