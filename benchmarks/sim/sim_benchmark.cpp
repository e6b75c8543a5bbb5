// Speed of the simulation core (numbers in docs/benchmarks.md):
//   build/benchmarks/sim/bench_sim
// Step: one control period, RunLoop::cycle on the simulated rig. Campaign: one run of paper_adaptive (18 s
// simulated); the counter `x_real_time` is simulated seconds per wall second.
#include <benchmark/benchmark.h>

#include <cmath>
#include <filesystem>
#include <memory>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/campaign/sim.hpp"
#include "hil/ctl/gap_fit.hpp"
#include "hil/physics.hpp"
#include "hil/plant/rng.hpp"

namespace {

using namespace hil::bench;

const Campaign& paper_adaptive() {
  static const Campaign c = load_campaign(std::filesystem::path(HIL_SOURCE_DIR) / "configs/campaigns/paper_adaptive.yaml");
  return c;
}

const RunSpec& run_named(const Campaign& c, const std::string& name) {
  for (const auto& r : c.runs)
    if (r.name == name) return r;
  throw std::runtime_error("no run " + name);
}

// One period of the bench's loop itself, RunLoop::cycle on the simulated rig (read, controller,
// interlocks, write, the plant's step, the record pushed and taken from the ring), as `hilbench
// sim` runs it, averaged over the 18 s run of paper_adaptive. Every 18 s the run starts again from
// a settled state (not timed), as a run does: carried on for hours instead, the chamber's free
// volume keeps growing as the grain burns, the chamber slows down, and a period gets ~20 % cheaper
// than in any real run (docs/benchmarks.md).
// compensator: the run's controller with another registered compensator (its defaults) instead.
void BM_Step(benchmark::State& state, const char* run_name, const char* compensator = nullptr) {
  const Campaign& c = paper_adaptive();
  RunSpec run = run_named(c, run_name);
  if (compensator != nullptr) {
    run.controller.compensator = compensator;
    run.controller.compensator_params.clear();  // its defaults
  }
  std::unique_ptr<SimulatedRun> sim;
  double p_meas_pa = 0;
  const auto take = [&p_meas_pa](const TelemetryRecord& r) { p_meas_pa = r.step.p_meas_pa; };
  for (auto _ : state) {
    if (!sim || !sim->next(take)) {
      state.PauseTiming();
      sim = std::make_unique<SimulatedRun>(c, run);  // as a run starts: the plant settled, the controller's initial state
      state.ResumeTiming();
      sim->next(take);
    }
    benchmark::DoNotOptimize(p_meas_pa);
  }
  state.counters["x_real_time"] = benchmark::Counter(c.period_s * state.iterations(), benchmark::Counter::kIsRate);
}
BENCHMARK_CAPTURE(BM_Step, robust_adaptive, "adaptive");
BENCHMARK_CAPTURE(BM_Step, paper_adaptive, "adaptive_paper");
BENCHMARK_CAPTURE(BM_Step, tracking_adaptive, "adaptive", "tracking");  // issue 42: within 1.5 x robust
BENCHMARK_CAPTURE(BM_Step, none, "none");

// A whole 18 s run without recording anything but the metrics.
void BM_Run(benchmark::State& state, const char* run_name) {
  const Campaign& c = paper_adaptive();
  const RunSpec& run = run_named(c, run_name);
  for (auto _ : state) benchmark::DoNotOptimize(summarise_run(c, run));
  state.counters["x_real_time"] = benchmark::Counter(c.duration_s * state.iterations(), benchmark::Counter::kIsRate);
}
BENCHMARK_CAPTURE(BM_Run, robust_adaptive, "adaptive")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Run, paper_adaptive, "adaptive_paper")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Run, none, "none")->Unit(benchmark::kMillisecond);

// One gap fit (the observer's measurement at a reversal) over a full 700-sample window: a 2 deg
// gap crossed at 8 deg/s behind the observer's two 15 ms low-pass stages, 0.02 deg of noise.
// Arg: 1 = four gaps to an AVX2 register where the CPU has it, 0 = two to an SSE2 register.
void BM_GapFit(benchmark::State& state) {
  constexpr double kDeg = 0.017453292519943295, kGap = 2 * kDeg, kAlpha = 0.06449301496838222;  // 1 - exp(-1/15.5)
  hil::ctl::GapFit::History h;
  hil::plant::Rng rng(7);
  double motor = 0.2, valve = motor + kGap / 2, lp1 = valve, lp2 = valve;
  for (int k = 0; k < 1024; ++k) {
    if (k > 300) motor += 8 * kDeg * 1e-3;
    valve = hil::physics::play_rad(valve, motor, kGap / 2);
    lp1 += kAlpha * (valve - lp1);
    lp2 += kAlpha * (lp1 - lp2);
    hil::ctl::GapFit::push(h, motor, lp2 + 0.02 * kDeg * rng.gaussian());
  }
  const hil::ctl::GapFit fit(kAlpha, 6 * kDeg);
  const bool wide = hil::ctl::GapFit::use_wide_lanes(state.range(0) != 0);
  if (wide != (state.range(0) != 0)) state.SkipWithError("this CPU has no AVX2");
  for (auto _ : state) benchmark::DoNotOptimize(fit.fit(h, 300, 0.2, +1, 400, 30));
  hil::ctl::GapFit::use_wide_lanes(true);
}
BENCHMARK(BM_GapFit)->Arg(0)->Arg(1)->ArgName("avx2")->Unit(benchmark::kMicrosecond);

// `hilbench sim paper_adaptive.yaml` end to end (all runs, report, and telemetry or not).
void BM_Campaign(benchmark::State& state) {
  const Campaign& c = paper_adaptive();
  const auto out = std::filesystem::temp_directory_path() / "hil_bench_sim";
  SimOptions options;
  options.out_dir = out;
  options.telemetry = state.range(0) != 0;
  options.progress = false;
  double simulated = 0;
  for (auto _ : state) simulated += run_campaign(c, options).simulated_s;
  std::filesystem::remove_all(out);
  state.counters["x_real_time"] = benchmark::Counter(simulated, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_Campaign)->Arg(0)->Arg(1)->ArgName("telemetry")->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
