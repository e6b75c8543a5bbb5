#include "slurm_script.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <iterator>
#include <tuple>

#include "cli.hpp"

namespace hil::bench {
namespace {

// A value as an error message shows it: at most 40 bytes, control characters as '?'.
std::string shown(std::string_view v) {
  std::string s(v.substr(0, 40));
  for (char& c : s) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '?';
  }
  return v.size() > 40 ? s + "... (" + std::to_string(v.size()) + " bytes)" : s;
}

bool digits(std::string_view s, std::size_t min, std::size_t max) {
  return s.size() >= min && s.size() <= max && std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

// Slurm's time formats: minutes, minutes:seconds, hours:minutes:seconds, days-hours,
// days-hours:minutes, days-hours:minutes:seconds; and UNLIMITED. Nine digits at most in a count
// (Slurm keeps minutes in 32 bits), two in a minutes or seconds field.
bool slurm_time(std::string_view t) {
  if (t == "UNLIMITED" || t == "INFINITE") return true;
  if (t.size() > 32) return false;
  const auto dash = t.find('-');
  if (dash != std::string_view::npos) {
    if (!digits(t.substr(0, dash), 1, 9)) return false;
    t.remove_prefix(dash + 1);
  }
  for (int field = 0;; ++field) {
    const auto colon = t.find(':');
    if (!digits(t.substr(0, colon), 1, field == 0 ? 9 : 2)) return false;
    if (colon == std::string_view::npos) return true;
    if (field == 2) return false;  // three fields at most
    t.remove_prefix(colon + 1);
  }
}

bool slurm_mem(std::string_view m) {
  if (!m.empty() && std::string_view("KMGT").find(m.back()) != std::string_view::npos) m.remove_suffix(1);
  return digits(m, 1, 15);
}

bool slurm_name(std::string_view n) {
  return !n.empty() && n.size() <= 128 && std::all_of(n.begin(), n.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || std::string_view("_.@+-").find(c) != std::string_view::npos;
  });
}

bool has_control(std::string_view s) {
  return std::any_of(s.begin(), s.end(), [](char c) { return static_cast<unsigned char>(c) < 0x20 || c == 0x7f; });
}

// sbatch's options (sbatch --help, slurm_opt.c): the name and whether it takes a value
// (1 required, 2 optional, 0 none). Only the names matter for abbreviations and separate values:
// an option not listed here passes as given, its value after '='.
struct LongOption {
  std::string_view name;
  int arg;
};
constexpr LongOption kLongOptions[] = {
    {"account", 1},
    {"acctg-freq", 1},
    {"array", 1},
    {"batch", 1},
    {"bb", 1},
    {"bbf", 1},
    {"begin", 1},
    {"chdir", 1},
    {"cluster-constraint", 1},
    {"clusters", 1},
    {"comment", 1},
    {"constraint", 1},
    {"container", 1},
    {"container-id", 1},
    {"contiguous", 0},
    {"core-spec", 1},
    {"cores-per-socket", 1},
    {"cpu-freq", 1},
    {"cpus-per-gpu", 1},
    {"cpus-per-task", 1},
    {"deadline", 1},
    {"delay-boot", 1},
    {"dependency", 1},
    {"distribution", 1},
    {"error", 1},
    {"exclude", 1},
    {"exclusive", 2},
    {"export", 2},
    {"export-file", 1},
    {"extra", 1},
    {"extra-node-info", 1},
    {"get-user-env", 2},
    {"gid", 1},
    {"gpu-bind", 1},
    {"gpu-freq", 1},
    {"gpus", 1},
    {"gpus-per-node", 1},
    {"gpus-per-socket", 1},
    {"gpus-per-task", 1},
    {"gres", 1},
    {"gres-flags", 1},
    {"help", 0},
    {"hint", 1},
    {"hold", 0},
    {"ignore-pbs", 0},
    {"input", 1},
    {"job-name", 1},
    {"kill-on-invalid-dep", 1},
    {"licenses", 1},
    {"mail-type", 1},
    {"mail-user", 1},
    {"mcs-label", 1},
    {"mem", 1},
    {"mem-bind", 1},
    {"mem-per-cpu", 1},
    {"mem-per-gpu", 1},
    {"mincpus", 1},
    {"network", 1},
    {"nice", 2},
    {"no-kill", 2},
    {"no-requeue", 0},
    {"nodefile", 1},
    {"nodelist", 1},
    {"nodes", 1},
    {"ntasks", 1},
    {"ntasks-per-core", 1},
    {"ntasks-per-gpu", 1},
    {"ntasks-per-node", 1},
    {"ntasks-per-socket", 1},
    {"open-mode", 1},
    {"output", 1},
    {"overcommit", 0},
    {"oversubscribe", 0},
    {"parsable", 0},
    {"partition", 1},
    {"power", 1},
    {"prefer", 1},
    {"priority", 1},
    {"profile", 1},
    {"propagate", 2},
    {"qos", 1},
    {"quiet", 0},
    {"reboot", 0},
    {"requeue", 0},
    {"reservation", 1},
    {"signal", 1},
    {"sockets-per-node", 1},
    {"spread-job", 0},
    {"switches", 1},
    {"test-only", 0},
    {"thread-spec", 1},
    {"threads-per-core", 1},
    {"time", 1},
    {"time-min", 1},
    {"tmp", 1},
    {"uid", 1},
    {"usage", 0},
    {"use-min-nodes", 0},
    {"verbose", 0},
    {"version", 0},
    {"wait", 0},
    {"wait-all-nodes", 1},
    {"wckey", 1},
    {"wrap", 1},
};
// Those the submission sets itself: given through --sbatch-arg they would split the sweep's logs
// from --status, or chain the jobs differently.
constexpr std::array<std::string_view, 10> kOwnLong = {"array",    "output", "error", "dependency", "job-name",
                                                       "parsable", "wrap",   "chdir", "input",      "open-mode"};
// sbatch's short options: those that take a value, those that take none; the submission's own.
constexpr std::string_view kShortWithValue = "aAbBcCdDeFGiJLmMnNopqStwx";
constexpr std::string_view kShortAlone = "hHkOQsvVW";
constexpr std::string_view kOwnShort = "aoedJDi";
constexpr std::array<std::string_view, 7> kOwnShortLong = {"array",    "output", "error", "dependency",
                                                           "job-name", "chdir",  "input"};

[[noreturn]] void refuse(const std::string& arg, const std::string& why) {
  throw UsageError("--sbatch-arg '" + shown(arg) + "': " + why);
}

// `name` as given ("--outp", "-o") is read by sbatch as `option` (empty: the same).
[[noreturn]] void refuse_own(const std::string& arg, const std::string& name, std::string_view option = {}) {
  refuse(arg, name + " is set by hilbench sweep --slurm itself (the array, its logs, the aggregation after it)" +
                  (option.empty() ? std::string() : "; sbatch reads '" + name + "' as --" + std::string(option)));
}

// A long option ("--name" or "--name=value"); whether the next argument is its value.
bool check_long(const std::string& arg) {
  const std::string name = arg.substr(2, arg.find('=') - 2);
  const bool valued = arg.find('=') != std::string::npos;
  if (name.empty()) refuse(arg, "no option name");
  // getopt_long: an exact name is that option; otherwise a prefix of exactly one is that one (a
  // prefix of several is refused by sbatch as ambiguous).
  const auto exact =
      std::find_if(std::begin(kLongOptions), std::end(kLongOptions), [&](const LongOption& o) { return o.name == name; });
  const auto owned = [](std::string_view n) { return std::find(kOwnLong.begin(), kOwnLong.end(), n) != kOwnLong.end(); };
  if (exact != std::end(kLongOptions)) {
    if (owned(exact->name)) refuse_own(arg, "--" + name);
    return exact->arg == 1 && !valued;
  }
  for (const auto own : kOwnLong) {
    if (own.substr(0, name.size()) == name) refuse_own(arg, "--" + name, own);
  }
  const LongOption* match = nullptr;
  int matches = 0;
  for (const auto& o : kLongOptions) {
    if (o.name.substr(0, name.size()) == name) match = &o, ++matches;
  }
  return matches == 1 && match->arg == 1 && !valued;
}

// A group of short options ("-vo/x", "-Qe", "-t10"); whether the next argument is a value.
bool check_short(const std::string& arg) {
  for (std::size_t i = 1; i < arg.size(); ++i) {
    const char c = arg[i];
    if (const auto own = kOwnShort.find(c); own != std::string_view::npos)
      refuse_own(arg, std::string("-") + c, kOwnShortLong[own]);
    if (kShortWithValue.find(c) != std::string_view::npos) return i + 1 == arg.size();  // the rest is its value
    if (kShortAlone.find(c) == std::string_view::npos) refuse(arg, std::string("-") + c + " is no sbatch option");
  }
  return false;
}

}  // namespace

void check_slurm_options(const SlurmOptions& o) {
  if (!o.time.empty() && !slurm_time(o.time))
    throw UsageError("--time '" + shown(o.time) + "': not a Slurm time limit (minutes, M:S, H:M:S, D-H, D-H:M or D-H:M:S)");
  if (!o.mem.empty() && !slurm_mem(o.mem))
    throw UsageError("--mem '" + shown(o.mem) + "': not a Slurm memory size (a whole number, optionally K, M, G or T)");
  for (const auto& [option, value, what] :
       {std::tuple{"--account", &o.account, "account"}, {"--qos", &o.qos, "QOS"}, {"--partition", &o.partition, "partition"}}) {
    if (!value->empty() && !slurm_name(*value))
      throw UsageError(std::string(option) + " '" + shown(*value) + "': not a Slurm " + what +
                       " name (letters, digits, _ . @ + -)");
  }
  // The arguments in order, as sbatch's getopt_long reads them: an option that takes a value and
  // has none attached takes the next argument.
  bool value_next = false;
  for (const auto& a : o.sbatch_args) {
    if (a.empty() || has_control(a)) refuse(a, "empty, or a control character in it");
    const bool was_value = value_next;
    value_next = false;
    if (a == "--") refuse(a, "ends sbatch's options: what follows would be taken as the job script");
    if (a.size() >= 2 && a[0] == '-') {
      // Checked as an option even where sbatch takes it as the value before: never a way past the refusals.
      value_next = a[1] == '-' ? check_long(a) : check_short(a);
      continue;
    }
    if (!was_value)
      refuse(a, "one sbatch option, as sbatch takes it (e.g. --constraint=avx2); a bare word would be taken as the job script");
  }
  if (value_next) refuse(o.sbatch_args.back(), "its value is missing (give it as --option=value)");
}

void check_slurm_folder(const std::filesystem::path& dir) {
  const std::string s = dir.string();
  if (has_control(s)) {
    throw UsageError("--out '" + shown(s) +
                     "': a folder name with a newline or another control character cannot go into a Slurm job script or "
                     "sbatch's --output safely; use another folder");
  }
  if (s.find('\\') != std::string::npos) {
    throw UsageError("--out '" + shown(s) +
                     "': a backslash in the folder name turns off sbatch's %A, %a and %j in --output (each task's log would "
                     "overwrite the others'); use another folder");
  }
}

std::string sh_quoted(std::string_view text) {
  std::string q = "'";
  for (char ch : text) q += ch == '\'' ? std::string("'\\''") : std::string(1, ch);
  return q + "'";
}

std::string slurm_file_pattern(const std::filesystem::path& dir, std::string_view pattern) {
  std::string out;
  for (char c : dir.string()) out += c == '%' ? std::string("%%") : std::string(1, c);
  if (!out.empty() && out.back() != '/') out += '/';
  return out + std::string(pattern);
}

SlurmScripts slurm_scripts(const std::string& exe, const std::filesystem::path& dir, const std::string& sweep_name, long tasks) {
  check_slurm_folder(dir);
  if (has_control(exe)) throw UsageError("the hilbench binary's path '" + shown(exe) + "' has a control character in it");
  std::string name = sweep_name;
  for (char& c : name) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '?';  // a comment line stays one line
  }
  const std::string head = "#!/bin/sh\n# Written by hilbench sweep --slurm for sweep " + name +
                           ": the nodes need this binary and the shared folder, nothing else.\n"
                           "# Its job name and logs (slurm/logs) are given on sbatch's command line (slurm/jobs.json).\n";
  const std::string run = "exec " + sh_quoted(exe) + " sweep --out " + sh_quoted(dir.string());
  return {head + "# Each task runs as many points at once as the CPUs Slurm gave it.\n" + run +
              " --shard \"${SLURM_ARRAY_TASK_ID}/" + std::to_string(tasks) + "\" --jobs \"${SLURM_CPUS_PER_TASK:-1}\"\n",
          head + run + " --aggregate\n"};
}

namespace {

std::vector<std::string> job_args(const std::filesystem::path& dir, const std::string& job_name, const std::string& log) {
  check_slurm_folder(dir);
  std::string name = job_name;
  for (char& c : name) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '_';
  }
  const auto logs = dir / "slurm" / "logs";
  return {"--job-name=" + name, "--output=" + slurm_file_pattern(logs, log + ".out"),
          "--error=" + slurm_file_pattern(logs, log + ".err")};
}

}  // namespace

// Logs per attempt (%A the array's job id, %j the aggregation's): a resubmission never overwrites
// the error of the attempt that failed.
std::vector<std::string> array_job_args(const std::filesystem::path& dir, const std::string& sweep_name) {
  return job_args(dir, "sweep-" + sweep_name, "shard-%A_%a");
}

std::vector<std::string> aggregate_job_args(const std::filesystem::path& dir, const std::string& sweep_name) {
  return job_args(dir, "sweep-" + sweep_name + "-aggregate", "aggregate-%j");
}

}  // namespace hil::bench
