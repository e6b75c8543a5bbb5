// hilbench sweep SWEEP.yaml [--out DIR] [--jobs N] [--quiet]        the points here, on every core
// hilbench sweep [SWEEP.yaml] --out DIR --shard I/N                     one shard's missing points (a Slurm task)
// hilbench sweep --out DIR --aggregate                                  the outputs, once every point is in
// hilbench sweep [SWEEP.yaml] --out DIR --slurm [--tasks N] [--max-parallel K] [sbatch options: --partition P --time T
//                  --mem M --account A --qos Q --cpus-per-task C --sbatch-arg OPT...]
// hilbench sweep --status DIR
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstdio>
#include <ctime>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <thread>

#include <spdlog/spdlog.h>

#include "commands.hpp"
#include "hil/bench/campaign/sim.hpp"  // Cancelled
#include "hil/bench/campaign/sweep.hpp"
#include "hil/json_file.hpp"
#include "hil/line_file.hpp"
#include "hil/text_file.hpp"
#include "sweep_slurm.hpp"

namespace hil::bench {
namespace {

using json = nlohmann::json;

struct SweepArgs {
  std::string sweep_file;
  std::string out_dir;
  int jobs = 0;  // 0: every hardware thread
  bool quiet = false;
  std::string shard;  // "I/N"
  bool aggregate = false;
  bool slurm = false;
  SlurmOptions slurm_options;
  std::string status_dir;
  std::vector<const CLI::Option*> slurm_only;  // options that only mean something with --slurm
};

// The plan in DIR, made from SWEEP.yaml when given: a folder planned from another sweep file (or
// another base campaign or plant) is refused, so rows of two sweeps never mix.
SweepPlan prepare(const SweepArgs& args, std::filesystem::path& dir) {
  if (args.sweep_file.empty()) {
    if (args.out_dir.empty()) throw UsageError("needs SWEEP.yaml, or --out DIR of a planned sweep");
    dir = args.out_dir;
    return read_plan(dir);
  }
  const auto dir_of = [&](const std::string& name) {
    return args.out_dir.empty() ? std::filesystem::path("out") / "sweeps" / name : std::filesystem::path(args.out_dir);
  };
  // A sweep being resumed: its points were checked when it was planned (a campaign load each,
  // seconds for a large sweep), so a plan with plan.json's hash skips that check.
  std::optional<SweepPlan> old;  // the folder's plan.json, read once
  const auto checked_hash = [&](const std::string& name) {
    if (std::filesystem::exists(dir_of(name) / "plan.json")) old = read_plan(dir_of(name));
    return old ? old->hash : std::string();
  };
  PlanCheckOptions check;
  check.progress = !args.quiet;
  check.cancel = &StopSignal::install();  // a large sweep's check takes minutes: Ctrl-C stops it, nothing written
  SweepPlan plan = plan_sweep(args.sweep_file, kMaxSweepPoints, checked_hash, check);
  dir = dir_of(plan.name);
  if (old) {
    if (old->hash != plan.hash) {
      throw std::runtime_error(dir.string() + " was planned from another sweep: " + args.sweep_file +
                               ", its base campaign, its plant or a file the campaign reads (a csv reference) changed since. Use "
                               "another --out, or remove " +
                               dir.string() + " to start this sweep afresh");
    }
    return *old;
  }
  write_plan(dir, plan);
  return plan;
}

std::pair<long, long> parse_shard(const std::string& text) {
  long i = -1, n = 0;
  char tail = 0;
  // N is bounded (a shard is at least one point of a sweep of at most ~1e6), which also keeps the
  // shard's stride I + kN from overflowing.
  if (std::sscanf(text.c_str(), "%ld/%ld%c", &i, &n, &tail) != 2 || n < 1 || n > 1000000 || i < 0 || i >= n) {
    throw UsageError("--shard " + text + ": needs I/N with 0 <= I < N <= 1000000, e.g. 0/4");
  }
  return {i, n};
}

int exit_after_signal(const SweepPlan& plan, const SweepRunResult& r) {
  spdlog::warn("sweep {}: stopped by {} after {} points (those in flight abandoned); {} of {} done; the same command continues",
               plan.name, StopSignal::name(), r.ran, r.done, r.total);
  return StopSignal::exit_code();
}

// Lines of DIR/rows/*.jsonl that read_rows skipped: part of --status's report (stdout), a
// warning of a run (the log).
std::string damaged_rows_line(const std::filesystem::path& dir, long damaged) {
  return "  " + std::to_string(damaged) + " line(s) in " + (dir / "rows").string() +
         " are no row of this sweep (damaged, or edited): skipped; a point without a good row counts as missing and is run "
         "again";
}

int jobs_of(const SweepArgs& args) {
  if (args.jobs > 0) return args.jobs;
  return std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

int aggregate(const std::filesystem::path& dir, const SweepPlan& plan, bool quiet) {
  const SweepOutputs out = write_sweep_outputs(dir, plan);
  if (out.missing > 0) {
    spdlog::error("sweep {}: {} of {} points missing in {}; nothing written (run the missing shards, then aggregate)", plan.name,
                  out.missing, plan.size(), dir.string());
    return 1;
  }
  if (!quiet) {
    std::printf("sweep %s: %ld points, %ld pass, %ld fail\n  %s\n  %s\n", plan.name.c_str(), plan.size(), out.passed,
                plan.size() - out.passed, (dir / "sweep.csv").c_str(), (dir / "report.html").c_str());
    // The worst few, each reproducible alone.
    const std::size_t shown = std::min<std::size_t>(3, out.worst.size());
    if (shown > 0) std::printf("  worst by %s:\n", plan.worst_by.c_str());
    for (std::size_t i = 0; i < shown; ++i) {
      std::printf("    hilbench sim %s\n", (dir / "points" / std::to_string(out.worst[i]) / "campaign.yaml").c_str());
    }
  }
  return 0;
}

int run_slurm(const SweepArgs& args) {
  std::filesystem::path dir;
  const SweepPlan plan = prepare(args, dir);
  dir = std::filesystem::absolute(dir).lexically_normal();
  const long tasks = std::min<long>(args.slurm_options.tasks, std::max<long>(1, plan.size()));
  const auto rows = read_rows(dir, plan);
  std::vector<long> shards;  // those with points still missing
  for (long i = 0; i < tasks; ++i) {
    for (long p = i; p < plan.size(); p += tasks) {
      if (!rows.count(p)) {
        shards.push_back(i);
        break;
      }
    }
  }
  if (shards.empty()) {
    std::printf("sweep %s: every point is in %s; aggregating here, nothing submitted\n", plan.name.c_str(), dir.c_str());
    return aggregate(dir, plan, args.quiet);
  }
  return submit_to_slurm(plan, dir, shards, tasks, plan.size() - static_cast<long>(rows.size()), args.slurm_options);
}

int run_status(const SweepArgs& args) {
  const std::filesystem::path dir = args.status_dir;
  const SweepPlan plan = read_plan(dir);
  long damaged = 0;
  const auto rows = read_rows(dir, plan, &damaged);
  const long done = static_cast<long>(rows.size());
  // The outputs are of every point; with points missing, those there are from an earlier state.
  // They are written all or none; one missing (an older hilbench, a hand) is said, not counted as written.
  int outputs = 0;
  for (const char* f : kSweepOutputs) outputs += std::filesystem::is_regular_file(dir / f) ? 1 : 0;
  std::printf("sweep %s: %ld of %ld points done, %ld missing%s\n", plan.name.c_str(), done, plan.size(), plan.size() - done,
              outputs == 0                          ? ""
              : outputs < std::ssize(kSweepOutputs) ? "; outputs incomplete (not all of sweep.csv, sweep.json, report.html)"
              : done == plan.size()                 ? "; outputs written"
                                                    : "; the outputs there are out of date (written before points went missing)");
  if (damaged > 0) std::printf("%s\n", damaged_rows_line(dir, damaged).c_str());
  return say_slurm_status(dir, plan.size() - done);
}

int run_sweep_mode(const SweepArgs& args);

int run_sweep_command(const SweepArgs& args) {
  try {
    return run_sweep_mode(args);
  } catch (const Cancelled&) {  // only the plan's check ends so (a run's points end in their result)
    spdlog::warn("sweep {}: stopped by {} while its points were checked; nothing was written", args.sweep_file,
                 StopSignal::name());
    return StopSignal::exit_code();
  }
}

int run_sweep_mode(const SweepArgs& args) {
  if (!args.status_dir.empty()) {
    if (!args.sweep_file.empty() || args.aggregate || args.slurm || !args.shard.empty())
      throw UsageError("--status DIR goes alone");
    return run_status(args);
  }
  const int modes = (args.aggregate ? 1 : 0) + (args.slurm ? 1 : 0) + (args.shard.empty() ? 0 : 1);
  if (modes > 1) throw UsageError("--shard, --aggregate and --slurm are separate modes: give one");
  if (!args.slurm) {
    for (const CLI::Option* o : args.slurm_only) {
      if (o->count() > 0) throw UsageError(o->get_name() + " goes with --slurm");
    }
  }
  if ((args.aggregate || !args.shard.empty()) && args.out_dir.empty()) throw UsageError("--shard and --aggregate need --out DIR");
  if (!args.aggregate && !args.slurm && args.shard.empty() && args.sweep_file.empty() && args.out_dir.empty())
    throw UsageError("needs SWEEP.yaml");
  if (args.slurm) {
    check_slurm_options(args.slurm_options);
    if (!args.out_dir.empty()) check_slurm_folder(std::filesystem::absolute(args.out_dir));  // before the folder is made
    return run_slurm(args);
  }

  std::filesystem::path dir;
  if (args.aggregate) {
    if (!args.sweep_file.empty()) throw UsageError("--aggregate reads the plan in --out DIR; no SWEEP.yaml");
    dir = args.out_dir;
    return aggregate(dir, read_plan(dir), args.quiet);
  }
  SweepRunOptions options;
  if (!args.shard.empty()) {  // a usage error before the folder and its plan are made
    const auto [i, n] = parse_shard(args.shard);
    options.shard = i;
    options.shards = n;
    options.rows_name = "shard-" + std::to_string(i) + "-of-" + std::to_string(n);
  }
  const SweepPlan plan = prepare(args, dir);
  options.jobs = jobs_of(args);
  options.progress = !args.quiet;
  options.cancel = &StopSignal::install();
  try {
    const SweepRunResult r = run_sweep(dir, plan, options);
    if (r.damaged_lines > 0) spdlog::warn("{}", damaged_rows_line(dir, r.damaged_lines));
    if (r.cancelled) return exit_after_signal(plan, r);
    if (!args.shard.empty()) {
      if (!args.quiet)
        std::printf("sweep %s shard %s: ran %ld points in %.2f s\n", plan.name.c_str(), args.shard.c_str(), r.ran, r.wall_s);
      return 0;
    }
    if (!args.quiet && r.ran > 0) {
      std::printf("sweep %s: ran %ld points in %.2f s (%.1f points/s on %d jobs)\n", plan.name.c_str(), r.ran, r.wall_s,
                  r.wall_s > 0 ? r.ran / r.wall_s : 0.0, options.jobs);
    }
    return aggregate(dir, plan, args.quiet);
  } catch (const std::exception&) {
    // A full disk, say, part way: say what is kept, so nobody starts afresh and loses the rest;
    // the error itself goes on to main, which shows each kind its own way.
    try {
      spdlog::warn("sweep {}: {} of {} points are kept in {}, and the same command goes on from there once the cause is fixed",
                   plan.name, read_rows(dir, plan).size(), plan.size(), dir.string());
    } catch (const std::exception&) {
      // The rows cannot be read either: the error below is the one to show.
    }
    throw;
  }
}

}  // namespace

CommandRun define_sweep(CLI::App& cmd) {
  auto args = std::make_shared<SweepArgs>();
  cmd.add_option("sweep", args->sweep_file, "the sweep file (optional with --out DIR of a planned sweep)")
      ->type_name("SWEEP.yaml");
  cmd.add_option("--out", args->out_dir, "the sweep's folder (default out/sweeps/<name>)")->type_name("DIR")->check(path_value());
  cmd.add_option("--jobs", args->jobs, "points run at once (default: every hardware thread)")
      ->type_name("N")
      ->check(whole_number(1, 4096));
  cmd.add_flag("--quiet", args->quiet, "no progress line and no summary");
  cmd.add_option("--shard", args->shard, "run only the missing points p with p % N == I (a Slurm task); no outputs")
      ->type_name("I/N");
  cmd.add_flag("--aggregate", args->aggregate, "write sweep.csv, sweep.json and report.html from every shard's rows");
  cmd.add_flag("--slurm", args->slurm, "submit the missing points as a Slurm job array and an aggregation job after it");
  auto& so = args->slurm_options;
  args->slurm_only = {
      cmd.add_option("--partition", so.partition, "Slurm partition (--slurm)")->type_name("P"),
      cmd.add_option("--max-parallel", so.max_parallel, "at most K array tasks at once (--slurm)")
          ->type_name("K")
          ->check(whole_number(1, 100000)),
      cmd.add_option("--tasks", so.tasks, "array tasks, each a shard of the points (--slurm)")
          ->type_name("N")
          ->check(whole_number(1, 100000))
          ->capture_default_str(),
      cmd.add_option("--time", so.time, "each job's time limit, as sbatch --time takes it (--slurm)")->type_name("LIMIT"),
      cmd.add_option("--mem", so.mem, "memory per node, as sbatch --mem takes it (--slurm)")->type_name("SIZE"),
      cmd.add_option("--account", so.account, "the account charged (--slurm)")->type_name("ACCOUNT"),
      cmd.add_option("--qos", so.qos, "quality of service (--slurm)")->type_name("QOS"),
      cmd.add_option("--cpus-per-task", so.cpus_per_task,
                     "CPUs of each array task; the task runs that many points at once (--slurm)")
          ->type_name("N")
          ->check(whole_number(1, 4096)),
      cmd.add_option("--sbatch-arg", so.sbatch_args, "any other sbatch option, passed as given; repeatable (--slurm)")
          ->type_name("OPTION")
          ->allow_extra_args(false),
  };
  cmd.add_option("--status", args->status_dir, "points done and missing, and the Slurm jobs' state")->type_name("DIR");
  return [args] { return run_sweep_command(*args); };
}

}  // namespace hil::bench
