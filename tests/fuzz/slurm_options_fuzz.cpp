// Fuzz target "slurm_options": the bytes as the Slurm options of `hilbench sweep --slurm`, one
// value per line: --time, --mem, --account, --qos, --partition, then every further line one
// --sbatch-arg (check_slurm_options, bench/src/cli/slurm_script.hpp). Each input is accepted or
// refused with a UsageError naming the option; when accepted, no argument may name an option the
// submission sets itself in any spelling sbatch's getopt_long takes (checked here independently:
// every prefix of the owned long names, every short letter of a group).
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>
#include <vector>

#include "cli/cli.hpp"
#include "cli/slurm_script.hpp"
#include "fuzz_support.hpp"

namespace {

// Whether an accepted argument list still reaches an option the submission owns.
bool reaches_owned(const std::vector<std::string>& args) {
  constexpr std::string_view kOwned[] = {"array",    "output", "error", "dependency", "job-name",
                                         "parsable", "wrap",   "chdir", "input",      "open-mode"};
  for (const auto& a : args) {
    if (a.rfind("--", 0) == 0) {
      const std::string name = a.substr(2, a.find('=') - 2);
      for (const auto own : kOwned) {
        if (!name.empty() && own.substr(0, name.size()) == name) return true;
      }
    } else if (a.size() >= 2 && a[0] == '-') {
      for (std::size_t i = 1; i < a.size(); ++i) {
        if (std::string_view("aoedJDi").find(a[i]) != std::string_view::npos) return true;
        if (std::string_view("AbBcCFGLmMnNpqStwx").find(a[i]) != std::string_view::npos) break;  // the rest is a value
      }
    }
  }
  return false;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::vector<std::string> lines;
  for (std::size_t from = 0; from <= text.size();) {
    const auto nl = std::min(text.find('\n', from), text.size());
    lines.push_back(text.substr(from, nl - from));
    from = nl + 1;
  }
  hil::bench::SlurmOptions o;
  std::string* fields[] = {&o.time, &o.mem, &o.account, &o.qos, &o.partition};
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (i < 5) {
      *fields[i] = lines[i];
    } else {
      o.sbatch_args.push_back(lines[i]);
    }
  }
  bool accepted = false;
  hil::fuzz::expect_clear_errors<hil::bench::UsageError>("check_slurm_options", [&] {
    hil::bench::check_slurm_options(o);
    accepted = true;
  });
  if (accepted && reaches_owned(o.sbatch_args)) {
    std::fprintf(stderr, "\nFINDING: an argument that sbatch reads as an option the submission sets was accepted\n");
    std::abort();
  }
  return 0;
}
