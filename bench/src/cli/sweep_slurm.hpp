// `hilbench sweep --slurm` and the Slurm half of `hilbench sweep --status`: what a cluster user
// expects of a job submitter (sbatch's resource options passed through, a log per attempt, final
// job states, a non-zero status while work is missing, the command that resubmits it).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "hil/bench/campaign/sweep.hpp"
#include "slurm_script.hpp"

namespace hil::bench {

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
