#include "sweep_slurm.hpp"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <map>
#include <set>
#include <sstream>

#include <spdlog/spdlog.h>

#include "cli.hpp"
#include "hil/json_file.hpp"
#include "hil/line_file.hpp"
#include "hil/text_file.hpp"

extern char** environ;

namespace hil::bench {
namespace {

using json = nlohmann::json;

std::string trimmed(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r' || s.back() == ' ')) s.pop_back();
  return s;
}

// The last non-empty line of a text.
std::string last_line(const std::string& text) {
  const auto end = text.find_last_not_of(" \r\n");
  if (end == std::string::npos) return "";
  const auto from = text.find_last_of('\n', end);
  return trimmed(text.substr(from == std::string::npos ? 0 : from + 1, end + 1 - (from == std::string::npos ? 0 : from + 1)));
}

// Runs `argv` (the program found on PATH), no shell between: every argument reaches it as it is.
// Its exit status (-1 when it could not run or died of a signal); stdout into `out`, stderr into `err`.
int run_program(const std::vector<std::string>& argv, std::string& out, std::string& err, const std::filesystem::path& scratch) {
  const auto out_file = scratch / ".cmd.out", err_file = scratch / ".cmd.err";
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 1, out_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  posix_spawn_file_actions_addopen(&fa, 2, err_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = 0;
  const int spawned = posix_spawnp(&pid, args[0], &fa, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  int raw = 0;
  if (spawned == 0) {
    while (::waitpid(pid, &raw, 0) < 0 && errno == EINTR) {}
  }
  std::error_code ec;
  out = std::filesystem::exists(out_file, ec) ? hil::read_text_file(out_file) : "";
  err = std::filesystem::exists(err_file, ec) ? hil::read_text_file(err_file) : "";
  std::filesystem::remove(out_file, ec);
  std::filesystem::remove(err_file, ec);
  if (spawned != 0) {
    err = argv[0] + ": cannot run: " + std::strerror(spawned);
    return -1;
  }
  return WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
}

bool on_path(const std::string& program) {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path != nullptr ? path : "");
  for (std::string d; std::getline(dirs, d, ':');) {
    if (!d.empty() && ::access((std::filesystem::path(d) / program).c_str(), X_OK) == 0) return true;
  }
  return false;
}

std::string sbatch(const std::vector<std::string>& args, const std::filesystem::path& scratch) {
  if (!on_path("sbatch"))
    throw std::runtime_error("sbatch not found on PATH: submitting needs Slurm's client (Debian: slurm-client)");
  std::vector<std::string> argv{"sbatch", "--parsable"};
  argv.insert(argv.end(), args.begin(), args.end());
  std::string out, err;
  const int status = run_program(argv, out, err, scratch);
  out = trimmed(out);
  const std::string id = out.substr(0, out.find(';'));  // "id;cluster" on a federation
  if (status != 0 || id.empty() || id.find_first_not_of("0123456789") != std::string::npos) {
    std::string cmd;
    for (const auto& a : argv) cmd += (cmd.empty() ? "" : " ") + a;
    throw std::runtime_error(cmd + " failed (exit " + std::to_string(status) + "): " + trimmed(err.empty() ? out : err));
  }
  return id;
}

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
  return buf;
}

// The options of a submission as sbatch arguments, in the order the flags are documented.
std::vector<std::string> common_sbatch_args(const SlurmOptions& o) {
  std::vector<std::string> a;
  if (!o.partition.empty()) a.push_back("--partition=" + o.partition);
  if (!o.time.empty()) a.push_back("--time=" + o.time);
  if (!o.mem.empty()) a.push_back("--mem=" + o.mem);
  if (!o.account.empty()) a.push_back("--account=" + o.account);
  if (!o.qos.empty()) a.push_back("--qos=" + o.qos);
  a.insert(a.end(), o.sbatch_args.begin(), o.sbatch_args.end());
  return a;
}

// The hilbench command line that submits the same way again (what --status tells to run).
std::string resubmit_command(const std::filesystem::path& dir, const json& submission) {
  std::string cmd =
      "hilbench sweep --out " + sh_quoted(dir.string()) + " --slurm --tasks " + std::to_string(submission.value("tasks", 8L));
  if (const long k = submission.value("max_parallel_asked", 0L); k > 0) cmd += " --max-parallel " + std::to_string(k);
  const json o = submission.value("options", json::object());
  for (const char* key : {"partition", "time", "mem", "account", "qos"}) {
    if (o.contains(key) && o[key].is_string() && !o[key].get<std::string>().empty())
      cmd += std::string(" --") + key + " " + sh_quoted(o[key].get<std::string>());
  }
  if (const int c = o.value("cpus_per_task", 0); c > 0) cmd += " --cpus-per-task " + std::to_string(c);
  if (o.contains("sbatch_args") && o["sbatch_args"].is_array()) {
    for (const auto& a : o["sbatch_args"])
      if (a.is_string()) cmd += " --sbatch-arg=" + sh_quoted(a.get<std::string>());  // '=': the value starts with a dash
  }
  return cmd;
}

// ---- job states ----------------------------------------------------------------------------

// One job or array task as Slurm reports it: "COMPLETED", "FAILED" ... and its exit code "1:0".
struct JobState {
  std::string state;
  std::string exit_code;
};

bool failed_state(const std::string& s) {
  static const std::set<std::string> kFailed = {"FAILED",    "TIMEOUT",   "CANCELLED", "OUT_OF_MEMORY",
                                                "NODE_FAIL", "PREEMPTED", "BOOT_FAIL", "DEADLINE"};
  return kFailed.count(s.substr(0, s.find(' '))) > 0;  // "CANCELLED by 0"
}

bool active_state(const std::string& s) {
  static const std::set<std::string> kActive = {"PENDING",   "RUNNING",      "CONFIGURING", "COMPLETING", "REQUEUED", "RESIZING",
                                                "SUSPENDED", "REQUEUE_HOLD", "REQUEUE_FED", "SIGNALING",  "STAGE_OUT"};
  return kActive.count(s) > 0;
}

// "123_4" -> "4", "123" -> "" (a plain job), "123_[5-7]" -> "[5-7]" (tasks not started yet).
std::string task_of(const std::string& job_id) {
  const auto u = job_id.find('_');
  return u == std::string::npos ? "" : job_id.substr(u + 1);
}

// The states of job `id` (each array task by its index, "" for a plain job), and where they came
// from, asked in this order: sacct (accounting: queued and finished jobs), scontrol (slurmctld
// knows queued jobs and keeps a finished one for MinJobAge, 300 s by default), squeue (queued
// only). Empty when no source knows the job any more.
std::map<std::string, JobState> job_states(const std::string& id, const std::filesystem::path& scratch, std::string& source) {
  std::map<std::string, JobState> states;
  std::string out, err;
  if (on_path("sacct") &&
      run_program({"sacct", "-n", "-P", "-X", "-j", id, "-o", "JobID,State,ExitCode"}, out, err, scratch) == 0) {
    std::stringstream lines(out);
    for (std::string l; std::getline(lines, l);) {
      std::stringstream f(l);
      std::string job, state, code;
      if (std::getline(f, job, '|') && std::getline(f, state, '|') && std::getline(f, code, '|'))
        states[task_of(job)] = {trimmed(state), trimmed(code)};
    }
    if (!states.empty()) {
      source = "sacct";
      return states;
    }
  }
  if (on_path("scontrol") && run_program({"scontrol", "-o", "show", "job", id}, out, err, scratch) == 0) {
    std::stringstream lines(out);
    for (std::string l; std::getline(lines, l);) {
      // "Key=value" fields parted by spaces; a value is what follows '=' up to the next space.
      std::string task, state, code;
      std::stringstream fields(l);
      for (std::string f; fields >> f;) {
        const auto eq = f.find('=');
        if (eq == std::string::npos || eq + 1 == f.size()) continue;
        const std::string key = f.substr(0, eq), value = f.substr(eq + 1);
        if (key == "ArrayTaskId") task = value;
        if (key == "JobState") state = value;
        if (key == "ExitCode") code = value;
      }
      if (!state.empty()) states[task] = {state, code};
    }
    if (!states.empty()) {
      source = "scontrol";
      return states;
    }
  }
  if (on_path("squeue") && run_program({"squeue", "-h", "-r", "-j", id, "-o", "%i|%T"}, out, err, scratch) == 0) {
    std::stringstream lines(out);
    for (std::string l; std::getline(lines, l);) {
      const auto bar = l.find('|');
      if (bar != std::string::npos) states[task_of(l.substr(0, bar))] = {trimmed(l.substr(bar + 1)), ""};
    }
    if (!states.empty()) source = "squeue";
  }
  return states;
}

// ---- logs ----------------------------------------------------------------------------------

// The logs of each array task, attempt by attempt: DIR/slurm/logs/shard-JOB_TASK.err (older
// hilbench wrote shard-TASK.err: job 0). Sorted by task, then by job id (the newest attempt last).
std::map<long, std::vector<std::pair<long, std::filesystem::path>>> task_logs(const std::filesystem::path& logs) {
  std::map<long, std::vector<std::pair<long, std::filesystem::path>>> by_task;
  std::error_code ec;
  const auto number = [](const std::string& s) {
    return !s.empty() && s.size() <= 18 && s.find_first_not_of("0123456789") == std::string::npos;
  };
  for (const auto& e : std::filesystem::directory_iterator(logs, ec)) {
    // shard-JOB_TASK.err, or shard-TASK.err
    const std::string name = e.path().filename().string();
    if (name.rfind("shard-", 0) != 0 || name.size() < 11 || name.substr(name.size() - 4) != ".err") continue;
    const std::string middle = name.substr(6, name.size() - 10);
    const auto u = middle.find('_');
    const std::string job = u == std::string::npos ? "0" : middle.substr(0, u);
    const std::string task = u == std::string::npos ? middle : middle.substr(u + 1);
    if (!number(job) || !number(task)) continue;
    by_task[std::stol(task)].emplace_back(std::stol(job), e.path());
  }
  for (auto& [task, files] : by_task) std::sort(files.begin(), files.end());
  return by_task;
}

std::string file_last_line(const std::filesystem::path& file) {
  try {
    return last_line(hil::read_text_file(file));
  } catch (const std::exception& e) {
    return e.what();
  }
}

}  // namespace

int submit_to_slurm(const SweepPlan& plan, const std::filesystem::path& dir, const std::vector<long>& shards, long tasks,
                    long missing, const SlurmOptions& o) {
  const auto slurm_dir = dir / "slurm";
  const std::string exe = std::filesystem::read_symlink("/proc/self/exe").string();
  const SlurmScripts scripts = slurm_scripts(exe, dir, plan.name, tasks);  // checks the folder's name first
  std::filesystem::create_directories(slurm_dir / "logs");
  replace_file(slurm_dir / "array.sh", scripts.array);
  replace_file(slurm_dir / "aggregate.sh", scripts.aggregate);
  std::filesystem::permissions(slurm_dir / "array.sh", std::filesystem::perms::owner_exec, std::filesystem::perm_options::add);
  std::filesystem::permissions(slurm_dir / "aggregate.sh", std::filesystem::perms::owner_exec,
                               std::filesystem::perm_options::add);

  std::string list;
  for (long i : shards) list += (list.empty() ? "" : ",") + std::to_string(i);
  const long parallel = o.max_parallel > 0 ? o.max_parallel : static_cast<long>(shards.size());
  const std::vector<std::string> common = common_sbatch_args(o);
  std::vector<std::string> array_args = common;
  if (o.cpus_per_task > 0) array_args.push_back("--cpus-per-task=" + std::to_string(o.cpus_per_task));
  array_args.push_back("--array=" + list + "%" + std::to_string(parallel));
  for (auto& a : array_job_args(dir, plan.name)) array_args.push_back(std::move(a));
  array_args.push_back((slurm_dir / "array.sh").string());
  const std::string array_id = sbatch(array_args, slurm_dir);
  std::vector<std::string> aggregate_args = common;  // one CPU: it reads rows and writes three files
  aggregate_args.push_back("--dependency=afterany:" + array_id);
  for (auto& a : aggregate_job_args(dir, plan.name)) aggregate_args.push_back(std::move(a));
  aggregate_args.push_back((slurm_dir / "aggregate.sh").string());
  const std::string aggregate_id = sbatch(aggregate_args, slurm_dir);

  json jobs = json::object();
  if (std::filesystem::exists(slurm_dir / "jobs.json")) {
    try {
      jobs = read_json_file(slurm_dir / "jobs.json");
    } catch (const std::exception& e) {
      spdlog::warn("sweep: {}; its earlier submissions are forgotten, this one is kept", e.what());
    }
    if (!jobs.is_object()) jobs = json::object();
  }
  if (!jobs.contains("submissions") || !jobs["submissions"].is_array()) jobs["submissions"] = json::array();
  jobs["submissions"].push_back({{"array", array_id},
                                 {"aggregate", aggregate_id},
                                 {"tasks", tasks},
                                 {"shards", shards},
                                 {"max_parallel", parallel},
                                 {"max_parallel_asked", o.max_parallel},
                                 {"partition", o.partition},
                                 {"options",
                                  {{"partition", o.partition},
                                   {"time", o.time},
                                   {"mem", o.mem},
                                   {"account", o.account},
                                   {"qos", o.qos},
                                   {"cpus_per_task", o.cpus_per_task},
                                   {"sbatch_args", o.sbatch_args}}},
                                 {"submitted_utc", utc_now()}});
  replace_file(slurm_dir / "jobs.json", jobs.dump(1) + "\n");
  std::printf(
      "sweep %s: %ld of %ld points missing; submitted array job %s (%zu tasks of %ld, at most %ld at once%s) and "
      "aggregation job %s\n  %s\n  hilbench sweep --status %s\n",
      plan.name.c_str(), missing, plan.size(), array_id.c_str(), shards.size(), tasks, parallel,
      o.cpus_per_task > 0 ? (", " + std::to_string(o.cpus_per_task) + " CPUs each").c_str() : "", aggregate_id.c_str(),
      (slurm_dir / "jobs.json").c_str(), dir.c_str());
  std::printf("array %s\naggregate %s\n", array_id.c_str(), aggregate_id.c_str());
  return 0;
}

int say_slurm_status(const std::filesystem::path& dir, long missing) {
  const auto jobs_file = dir / "slurm" / "jobs.json";
  if (!std::filesystem::exists(jobs_file)) {
    if (missing == 0) return 0;
    std::printf("  to run what is missing: hilbench sweep --out %s (here), or with --slurm\n", sh_quoted(dir.string()).c_str());
    return 1;
  }
  json jobs;
  try {
    jobs = read_json_file(jobs_file);
  } catch (const std::exception& e) {
    std::printf("  %s\n", e.what());
    return 1;
  }
  if (!jobs.is_object() || !jobs.contains("submissions") || !jobs["submissions"].is_array() || jobs["submissions"].empty()) {
    std::printf("  %s: no list of submissions\n", jobs_file.c_str());
    return 1;
  }
  const auto& submissions = jobs["submissions"];
  bool active = false, failed = false;
  std::vector<std::string> failures;
  for (std::size_t s = 0; s < submissions.size(); ++s) {
    const json& sub = submissions[s];
    const bool newest = s + 1 == submissions.size();
    for (const char* kind : {"array", "aggregate"}) {
      const std::string id = sub.value(kind, "");
      std::string source;
      const auto states = id.empty() ? std::map<std::string, JobState>{} : job_states(id, dir / "slurm", source);
      std::string said;
      if (states.empty()) {
        said =
            "finished; Slurm no longer knows its state (no accounting for sacct, and slurmctld forgets a job MinJobAge after it "
            "ends)";
      } else {
        std::map<std::string, int> counts;
        for (const auto& [task, st] : states) {
          ++counts[st.state];
          if (active_state(st.state)) active = true;
          if (!failed_state(st.state)) continue;
          // Only the newest submission's failures make the sweep fail: an older one was resubmitted.
          if (newest) failed = true;
          std::string what = std::string(kind) + " job " + id + (task.empty() ? "" : "_" + task) + " " + st.state +
                             (st.exit_code.empty() ? "" : " (exit " + st.exit_code + ")");
          const auto log = std::string(kind) == "array" ? dir / "slurm" / "logs" / ("shard-" + id + "_" + task + ".err")
                                                        : dir / "slurm" / "logs" / ("aggregate-" + id + ".err");
          if (std::filesystem::exists(log)) what += ": " + file_last_line(log) + "\n      (" + log.string() + ")";
          if (newest) failures.push_back(what);
        }
        for (const auto& [st, n] : counts) said += (said.empty() ? "" : ", ") + st + (n > 1 ? " x" + std::to_string(n) : "");
        said += " (" + source + ")";
      }
      std::printf("  %s job %s (submitted %s): %s\n", kind, id.c_str(), sub.value("submitted_utc", "?").c_str(), said.c_str());
    }
  }
  // Each task's last progress line, from its newest attempt's log.
  for (const auto& [task, files] : task_logs(dir / "slurm" / "logs")) {
    const std::string last = file_last_line(files.back().second);
    std::printf("  task %ld: %s%s\n", task, last.empty() ? "(no output yet)" : last.c_str(),
                files.size() > 1 ? (" [attempt " + std::to_string(files.size()) + "; earlier logs kept]").c_str() : "");
  }
  // The aggregation's own error (points missing, a full disk): it is the one job that says why
  // there is no sweep.csv.
  const std::string aggregate_id = submissions.back().value("aggregate", "");
  const auto aggregate_err = dir / "slurm" / "logs" / ("aggregate-" + aggregate_id + ".err");
  if (std::filesystem::exists(aggregate_err)) {
    const std::string last = file_last_line(aggregate_err);
    if (!last.empty()) std::printf("  aggregation job %s said: %s\n", aggregate_id.c_str(), last.c_str());
  }
  for (const auto& f : failures) std::printf("  FAILED: %s\n", f.c_str());
  if (missing == 0 && !failed) return 0;
  if (active && !failed) {
    std::printf("  still running: %ld points to go\n", missing);
    return 3;
  }
  if (missing > 0) {
    std::printf("  %ld points missing and nothing left to run them; to run what is missing:\n    %s\n", missing,
                resubmit_command(dir, submissions.back()).c_str());
  }
  return 1;
}

}  // namespace hil::bench
