// What `hilbench sweep --slurm` hands to Slurm, made from data and checked before anything runs:
// the sbatch options (each value against what sbatch accepts, --sbatch-arg read as sbatch's
// getopt_long reads it), the sweep folder's name (it reaches sbatch's --output and the job
// scripts), and the job scripts themselves, whose only variable parts are quoted for sh. No
// regular expression reads a value: a 60 000-digit --time overflowed std::regex's stack.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

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
// would take over what the submission itself sets (--array, --output, --dependency, ...) however
// sbatch would read it: a unique abbreviation (--outp=, --arr=), a short option inside a group
// (-vo..., -Qe...), with its value after '=', attached or in the next argument; a bare argument
// sbatch would take as the job script, and "--", are refused too.
void check_slurm_options(const SlurmOptions& o);

// Throws UsageError when `dir` (the sweep folder, as --out gave it or made absolute) cannot reach
// a job script and sbatch's --output safely: a control character (a newline put a command of its
// own into array.sh) or a backslash (it turns off sbatch's %A/%a/%j in --output). Anything else
// is quoted where it goes.
void check_slurm_folder(const std::filesystem::path& dir);

// `text` quoted for sh: in single quotes, a single quote as '\''.
std::string sh_quoted(std::string_view text);

// A file name for sbatch's --output / --error: '%' doubled (a literal percent sign), then
// `pattern` (with its own %A, %a or %j) appended.
std::string slurm_file_pattern(const std::filesystem::path& dir, std::string_view pattern);

// The job scripts of a submission: array.sh runs shard ${SLURM_ARRAY_TASK_ID} of `tasks`,
// aggregate.sh the aggregation, both this binary (`exe`) on `dir`. check_slurm_folder(dir) and
// the same check of `exe` first (throws UsageError).
struct SlurmScripts {
  std::string array, aggregate;
};
SlurmScripts slurm_scripts(const std::string& exe, const std::filesystem::path& dir, const std::string& sweep_name, long tasks);

// The sbatch options each job is named and logged with (given on sbatch's command line, never in
// the script): --job-name, --output and --error under DIR/slurm/logs.
std::vector<std::string> array_job_args(const std::filesystem::path& dir, const std::string& sweep_name);
std::vector<std::string> aggregate_job_args(const std::filesystem::path& dir, const std::string& sweep_name);

}  // namespace hil::bench
