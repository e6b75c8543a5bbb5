// Speed of the simulation core (numbers in docs/benchmarks.md):
//   build/benchmarks/sim/bench_sim
// Step: one control period, plant + controller. Campaign: one run of paper_adaptive (18 s
// simulated); the counter `x_real_time` is simulated seconds per wall second.
#include <benchmark/benchmark.h>

#include <filesystem>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/campaign/sim.hpp"

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

// One period of the loop: controller step on the reading, then the plant step.
void BM_Step(benchmark::State& state, const char* run_name) {
  const Campaign& c = paper_adaptive();
  const RunSpec& run = run_named(c, run_name);
  const auto& plant = *c.plant;
  auto ps = plant.make_state(1);
  plant.settle(ps, 1.0e6);
  const hil::ctl::Controller ctl(run.controller);
  auto cs = ctl.initial_state(ps.s.theta_cmd_rad, ps.s.p_meas_pa, +1);
  // The schedules read through cursors, as the run loop reads them (time only moves forward
  // there; here it jumps back to 0 every 18 s, which a cursor also handles).
  Schedule::Cursor ref_cursor, gap_cursor;
  long k = 0;
  for (auto _ : state) {
    const double t = (k++ % 18000) * 1e-3;
    const double ref = c.reference_pa.at(t, ref_cursor);
    const auto out = ctl.step(cs, {ps.s.p_meas_pa, ref, ps.s.theta_motor_rad});
    plant.step(ps, {out.theta_cmd_rad, hil::plant::kNaN, c.gap_rad.at(t, gap_cursor)}, 1e-3);
    benchmark::DoNotOptimize(ps.s.p_meas_pa);
  }
  state.counters["x_real_time"] = benchmark::Counter(1e-3 * state.iterations(), benchmark::Counter::kIsRate);
}
BENCHMARK_CAPTURE(BM_Step, robust_adaptive, "adaptive");
BENCHMARK_CAPTURE(BM_Step, paper_adaptive, "adaptive_paper");
BENCHMARK_CAPTURE(BM_Step, none, "none");

// A whole 18 s run without recording anything but the metrics.
void BM_Run(benchmark::State& state, const char* run_name) {
  const Campaign& c = paper_adaptive();
  const RunSpec& run = run_named(c, run_name);
  for (auto _ : state) benchmark::DoNotOptimize(summarise_run(c, run));
  state.counters["x_real_time"] = benchmark::Counter(c.duration_s * state.iterations(), benchmark::Counter::kIsRate);
}
BENCHMARK_CAPTURE(BM_Run, robust_adaptive, "adaptive")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Run, none, "none")->Unit(benchmark::kMillisecond);

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
