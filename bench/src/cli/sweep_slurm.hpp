// `hilbench sweep --slurm` and the Slurm half of `hilbench sweep --status`: what a cluster user
// expects of a job submitter (sbatch's resource options passed through, a log per attempt, final
// job states, a non-zero status while work is missing, the command that resubmits it).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "hil/bench/campaign/sweep.hpp"

namespace hil::bench {

// sbatch options of a submission. Empty strings and 0 are "not given" (Slurm's own defaults).
struct SlurmOptions {
  std::string partition;
  std::string time;                      // --time, a Slurm time limit ("90", "1:30:00", "2-00")
  std::string mem;                       // --mem per node ("4G")
  std::string account;                   // --account
  std::string qos;                       // --qos
  int cpus_per_task = 0;                 // --cpus-per-task of the array's tasks (each task runs --jobs this many points)
  int max_parallel = 0;                  // at most this many tasks at once (0: all)
  int tasks = 8;                         // shards of the sweep
  std::vector<std::string> sbatch_args;  // anything else, passed to sbatch as given ("--constraint=avx2")
};

// Throws UsageError naming the option for a value Slurm would refuse, or an sbatch argument that
// would take over what the submission itself sets (--array, --output, --dependency, ...).
void check_slurm_options(const SlurmOptions& o);

// Submits the shards of `plan` that still miss points (`shards`, of `tasks`) as a job array and
// an aggregation job after it; writes DIR/slurm/{array,aggregate}.sh and appends the submission to
// DIR/slurm/jobs.json. `dir` is absolute. Prints the job ids; returns the exit status.
int submit_to_slurm(const SweepPlan& plan, const std::filesystem::path& dir, const std::vector<long>& shards, long tasks,
                    long missing, const SlurmOptions& o);

// The jobs of DIR/slurm/jobs.json with their states (sacct, else scontrol, else squeue), each task's last progress line from the newest attempt's log, the aggregation
// job's error, and the command that resubmits what is missing. Returns the exit status of
// `--status`: 0 when no point is missing, 3 while jobs still run and none failed, 1 when a task
// or the aggregation failed or points are missing with nothing left to run them.
int say_slurm_status(const std::filesystem::path& dir, long missing);

}  // namespace hil::bench
