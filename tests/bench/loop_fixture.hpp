// Helpers for driving a RunLoop without a clock: period k wakes exactly on its deadline and
// computes for `compute` (tests choose the times, so nothing here depends on the machine).
#pragma once

#include <chrono>
#include <memory>
#include <vector>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/rt/rt_loop.hpp"
#include "hil/bench/rt/sim_rig.hpp"
#include "temp_file.hpp"

namespace hil::test {

using namespace std::chrono_literals;
using bench::Clock;

inline const bench::Campaign& paper_adaptive() {
  static const bench::Campaign c = bench::load_campaign(source_path("configs/campaigns/paper_adaptive.yaml"));
  return c;
}

inline bench::Campaign short_campaign(double duration_s) {
  bench::Campaign c = paper_adaptive();
  c.duration_s = duration_s;
  return c;
}

inline const bench::RunSpec& run_named(const bench::Campaign& c, const std::string& name) {
  for (const auto& r : c.runs) {
    if (r.name == name) return r;
  }
  throw std::invalid_argument(name);
}

inline Clock::time_point fake_now() noexcept { return Clock::time_point{}; }

// A RunLoop on a SimRig with rings big enough for the whole run unless told otherwise.
struct LoopHarness {
  explicit LoopHarness(const bench::Campaign& campaign, const std::string& run = "adaptive", bench::SafetyConfig safety = {},
                       bench::LoopConfig loop_cfg = {}, std::size_t ring = 1 << 15)
      : c(campaign), telemetry(ring), events(1024), requests(64) {
    rig.configure({&c, c.period_s, c.reference_pa.at(0.0), c.gap_rad.at(0.0)});
    rig.activate();
    period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(c.period_s));
    loop = std::make_unique<bench::RunLoop>(c, run_named(c, run), rig, safety, loop_cfg, period, telemetry, events, requests,
                                            &fake_now);
    loop->begin(t0);
  }
  // One period; `late` makes it end that long after its deadline. False once the run ended.
  bool step(Clock::duration compute = 20us) {
    const auto deadline = t0 + k * period;
    loop->cycle(deadline, deadline);
    ++k;
    return loop->finish_cycle(deadline + compute);
  }
  std::vector<bench::TelemetryRecord> rows() {
    std::vector<bench::TelemetryRecord> out(telemetry.size());
    out.resize(telemetry.pop(out.data(), out.size()));
    return out;
  }
  std::vector<bench::LoopEvent> take_events() {
    std::vector<bench::LoopEvent> out(events.size());
    out.resize(events.pop(out.data(), out.size()));
    return out;
  }

  bench::Campaign c;
  bench::SimRig rig;
  bench::SpscRing<bench::TelemetryRecord> telemetry;
  bench::SpscRing<bench::LoopEvent> events;
  bench::SpscRing<bench::LoopRequest> requests;
  Clock::duration period{};
  Clock::time_point t0 = Clock::time_point{} + 1s;
  long k = 0;
  std::unique_ptr<bench::RunLoop> loop;
};

}  // namespace hil::test
