// Workbench speed: `compare` on one hour at 1 kHz (3.6 M rows) and `diagnose` with all candidates
// on ten minutes at 1 kHz, on closed-loop files generated here (bench's simulate_run, controller
// on the nominal plant, hidden effects in the simulated truth). Prints wall time, rows per second
// and the peak resident memory each step added.
//   bench_analysis [--keep DIR] [--threads N] [--only compare|diagnose|three|three-30s|three-600s]
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>

#include "hil/analysis/compare.hpp"
#include "hil/analysis/diagnose.hpp"
#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/campaign/sim.hpp"
#include "hil/config.hpp"
#include "hil/csv_writer.hpp"
#include "hil/plant/registry.hpp"
#include "hil/units.hpp"

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

const fs::path kNominal = fs::path(HIL_SOURCE_DIR) / "configs/plant/nominal.yaml";

long peak_rss_kb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss;
}

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }
// The process's CPU time (user + system, all threads) [s]: on a shared, loaded machine the wall
// time says more about the others than about this code; CPU time / threads is what an idle
// machine with that many cores would take at best.
double cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

// The calling thread's own CPU time [s]. diagnose's calling thread takes part in every parallel
// loop and runs the serial parts alone, so on a machine with nothing else to do its wall time is
// at least this (and at least the process's CPU time over the threads): the larger of the two is
// the quiet-machine estimate that a loaded machine still lets one measure.
double thread_cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_THREAD, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

hil::plant::Plant with_block(const hil::plant::Plant& p, const std::string& kind, const std::string& yaml) {
  return p.with(hil::plant::find_effect(kind)->from_yaml(hil::cfg::Node::load_string(yaml, kind)));
}

// A closed-loop run written as a measurement file (t_s, theta_cmd_deg, p_meas_mpa, [theta_motor_deg], p_ref_mpa).
fs::path make_file(const fs::path& dir, const std::string& name, double duration_s, bool encoder,
                   const std::function<hil::plant::Plant(const hil::plant::Plant&)>& truth) {
  const std::string yaml = "name: " + name + "\nplant: " + kNominal.string() + "\nduration_s: " + std::to_string(duration_s) +
                           "\nperiod_ms: 1\nseed: 9\nsensor_noise_kpa: 2.0\nreference:\n  initial_mpa: 1.2\n  profile:\n"
                           "    - random: {seed: 3, from_s: 1.0, min_mpa: 0.9, max_mpa: 1.6, dwell_s: [1.5, 5.0], "
                           "ramp_probability: 0.4, ramp_s: [0.3, 1.5]}\n"
                           "controller:\n  observer: robust\nruns:\n  - name: run\n    compensation: adaptive\n";
  hil::bench::Campaign c = hil::bench::load_campaign_text(yaml, name + ".yaml", dir);
  c.plant = std::make_shared<const hil::plant::Plant>(truth(*c.plant));
  std::vector<hil::CsvColumn> cols = {{"t_s", 4}, {"theta_cmd_deg", 5}, {"p_meas_mpa", 6}};
  if (encoder) cols.push_back({"theta_motor_deg", 5});
  cols.push_back({"p_ref_mpa", 6});
  const fs::path file = dir / (name + ".csv");
  hil::CsvWriter w(file, cols, {{"source", "bench_analysis"}});
  std::vector<double> row;
  hil::bench::simulate_run(c, c.runs.front(), [&](const hil::bench::TelemetryRecord& rec) {
    const hil::bench::StepRecord& r = rec.step;
    row = {r.t_s, hil::units::rad_to_deg(r.theta_cmd_rad), hil::units::pa_to_mpa(r.p_meas_pa)};
    if (encoder) row.push_back(hil::units::rad_to_deg(r.theta_motor_rad));
    row.push_back(hil::units::pa_to_mpa(r.p_ref_pa));
    w.row(row);
  });
  w.close();
  return file;
}

void bench_compare(const fs::path& dir) {
  auto t0 = Clock::now();
  const fs::path file = make_file(dir, "hour", 3600, true, [](const hil::plant::Plant& p) { return p; });
  std::printf("compare: generated %s (%.0f MB) in %.1f s\n", file.filename().c_str(),
              static_cast<double>(fs::file_size(file)) / 1e6, seconds_since(t0));
  const long rss0 = peak_rss_kb();
  t0 = Clock::now();
  hil::analysis::CompareOptions o;
  o.model_file = kNominal;
  o.data_file = file;
  o.out_dir = dir / "compare";
  o.quiet = true;
  const auto r = hil::analysis::run_compare(o);
  const double wall = seconds_since(t0);
  std::printf("compare: %zu rows in %.2f s (%.2f M rows/s), fit %.2f %% (floor %.2f %%), peak RSS %ld MB (was %ld MB)\n", r.rows,
              wall, r.rows / wall / 1e6, r.fit_pct, r.noise_floor_fit_pct, peak_rss_kb() / 1024, rss0 / 1024);
}

void bench_diagnose(const fs::path& dir, unsigned threads, const std::string& name,
                    const std::function<hil::plant::Plant(const hil::plant::Plant&)>& truth, double duration_s = 600) {
  auto t0 = Clock::now();
  const fs::path file = make_file(dir, name, duration_s, false, truth);
  std::printf("diagnose %s: generated %.0f MB in %.1f s\n", name.c_str(), static_cast<double>(fs::file_size(file)) / 1e6,
              seconds_since(t0));
  t0 = Clock::now();
  const double cpu0 = cpu_seconds(), own0 = thread_cpu_seconds();
  hil::analysis::DiagnoseOptions o;
  o.model_file = kNominal;
  o.data_files = {file};
  o.out_dir = dir / ("diagnose-" + name);
  o.quiet = true;
  o.settings.threads = threads;
  const auto d = hil::analysis::run_diagnose(o);
  const double wall = seconds_since(t0), cpu = cpu_seconds() - cpu0, own = thread_cpu_seconds() - own0;
  std::string found;
  for (const auto& a : d.added) found += (found.empty() ? "" : " + ") + a.effect;
  std::printf(
      "diagnose %s: %zu rows, %u threads, %.1f s wall, %.1f s CPU (calling thread %.1f s; quiet-machine estimate %.1f s), "
      "%d replays, coarse copy 1:%zu, found %s, fit %.2f -> %.2f %% (floor %.2f %%), peak RSS %ld MB\n",
      name.c_str(), d.rows, threads, wall, cpu, own, std::max(own, cpu / threads), d.evaluations, d.decimation,
      found.empty() ? "nothing" : found.c_str(), d.before.fit_pct, d.after.fit_pct, d.noise_floor_fit_pct, peak_rss_kb() / 1024);
}

}  // namespace

int main(int argc, char** argv) {
  fs::path keep;
  unsigned threads = 2;
  std::string only;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--keep" && i + 1 < argc)
      keep = argv[++i];
    else if (a == "--threads" && i + 1 < argc)
      threads = static_cast<unsigned>(std::stoul(argv[++i]));
    else if (a == "--only" && i + 1 < argc)
      only = argv[++i];
    else {
      std::fprintf(stderr,
                   "usage: bench_analysis [--keep DIR] [--threads N] [--only compare|diagnose|three|three-30s|three-600s]\n");
      return 2;
    }
  }
  const fs::path dir = keep.empty() ? fs::temp_directory_path() / ("bench_analysis_" + std::to_string(::getpid())) : keep;
  fs::create_directories(dir);
  std::setvbuf(stdout, nullptr, _IOLBF, 0);  // each figure as it comes, also into a file
  std::printf("bench_analysis: %s, %u hardware threads\n", dir.c_str(), std::thread::hardware_concurrency());
  if (only.empty() || only == "compare") bench_compare(dir);
  // Three effects at once: gap 1.7 deg, erosion 0.5 mm^2/s, sensor offset 25 kPa.
  auto three = [](const hil::plant::Plant& p) {
    return with_block(with_block(with_block(p, "backlash_change", "gap_deg: 1.7"), "throat_erosion", "rate_mm2_per_s: 0.5"),
                      "sensor_bias", "{offset_kpa: 25, gain: 1.0}");
  };
  if (only.empty() || only == "three" || only == "three-30s") bench_diagnose(dir, threads, "three-effects-30s", three, 30);
  if (only.empty() || only == "three" || only == "three-600s") bench_diagnose(dir, threads, "three-effects-600s", three, 600);
  if (only.empty() || only == "diagnose") {
    bench_diagnose(dir, threads, "no-effect", [](const hil::plant::Plant& p) { return p; });
    bench_diagnose(dir, threads, "one-effect",
                   [](const hil::plant::Plant& p) { return with_block(p, "sensor_lag", "time_constant_s: 0.03"); });
    bench_diagnose(dir, threads, "two-effects", [](const hil::plant::Plant& p) {
      return with_block(with_block(p, "valve_offset", "offset_deg: 1.2"), "sensor_lag", "time_constant_s: 0.03");
    });
    bench_diagnose(dir, threads, "gap-step", [](const hil::plant::Plant& p) {
      return with_block(p, "backlash_change", "{gap_deg: 1.0, step_time_s: 290, step_deg: 0.8}");
    });
    // Worst case: a throat map with a kink no candidate has; several candidates mimic part of it,
    // so the search follows three paths.
    bench_diagnose(dir, threads, "kinked-map", [](const hil::plant::Plant& p) {
      return with_block(p, "throat_map", "{angle_deg: [0, 8, 14, 30], area_mm2: [40, 62, 90, 140]}");
    });
  }
  if (keep.empty()) fs::remove_all(dir);
  return 0;
}
