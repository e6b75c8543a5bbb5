// What the hilbench sub-commands share on top of CLI11: the error for a bad invocation found past
// parsing, the shape of a sub-command, and the number checks, worded alike for every option.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>

#include <CLI/CLI.hpp>

namespace hil::bench {

// A bad invocation that CLI11 cannot see (options that go only together, a malformed address):
// exit 2 with the sub-command's usage, like CLI11's own parse errors.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A sub-command's job once its command line is parsed; returns the process exit code.
using CommandRun = std::function<int()>;

// Checks for number options; CLI11 prefixes each message with the option's name
// ("--period-ms: needs a number, got 'fast'"). Every one refuses inf and nan. Ours rather than
// CLI::NonNegativeNumber or CLI::Range: those name their bound as std::to_string(DBL_MAX), 300 digits.
CLI::Validator finite_number();
CLI::Validator non_negative_number();
CLI::Validator number_in(double min, double max);                 // min..max, both included
CLI::Validator whole_number(std::int64_t min, std::int64_t max);  // max INT64_MAX: no upper bound
// For a path option: refuses "" (`--out=`: the files would land in the current folder or fail
// with a bare "Invalid argument") and a value that is an option (`--out= --quiet` took --quiet
// as the folder).
CLI::Validator path_value();

// Ctrl-C and SIGTERM as a request to stop long work: from install() on, either signal sets the
// flag the work polls, so it ends cleanly instead of dying mid-write.
struct StopSignal {
  // What a signal after the first does. Offline work (`sim`, `sweep`, `report`): the process
  // ends at once, for work blocked where it cannot poll. A bench run (`hilbench run`): nothing
  // but a line on stderr; the abort under way takes the rig to its safe state and writes the
  // record first, however often Ctrl-C is pressed (SIGQUIT, Ctrl-\, still kills at once).
  enum class Repeat { exits, waits_for_safe_state };
  static const std::atomic<bool>& install(Repeat repeat = Repeat::exits);
  static const char* name();  // "SIGTERM" or "SIGINT" (also before any signal)
  static int exit_code();     // 128 + the signal, as a shell reports a death by it
};

// Adds sub-command `name` to `parent` in the "Commands" group of the help.
CLI::App* add_command(CLI::App& parent, const std::string& name, const std::string& summary);

}  // namespace hil::bench
