#include "cli.hpp"

#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>

namespace hil::bench {
namespace {

// `text` as a finite number; false when it is not one (trailing text, inf, nan, empty).
bool to_finite(const std::string& text, double& value) {
  char* end = nullptr;
  value = std::strtod(text.c_str(), &end);
  return !text.empty() && end == text.c_str() + text.size() && std::isfinite(value);
}

}  // namespace

CLI::Validator finite_number() {
  return CLI::Validator(
      [](std::string& text) {
        double v = 0;
        return to_finite(text, v) ? std::string() : "needs a number, got '" + text + "'";
      },
      "");
}

CLI::Validator non_negative_number() {
  return CLI::Validator(
      [](std::string& text) {
        double v = 0;
        if (!to_finite(text, v)) return "needs a number, got '" + text + "'";
        return v >= 0 ? std::string() : "cannot be negative, got " + text;
      },
      ">= 0");
}

CLI::Validator number_in(double min, double max) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%g..%g", min, max);
  const std::string range = buf;
  return CLI::Validator(
      [min, max, range](std::string& text) {
        double v = 0;
        return to_finite(text, v) && v >= min && v <= max ? std::string() : "needs a number in " + range + ", got '" + text + "'";
      },
      range);
}

CLI::Validator path_value() {
  return CLI::Validator(
      [](std::string& text) {
        if (text.empty()) return std::string("needs a path, got an empty one");
        if (text.rfind("--", 0) == 0) return "needs a path, got the option '" + text + "' (is the path missing?)";
        return std::string();
      },
      "");
}

CLI::Validator whole_number(std::int64_t min, std::int64_t max) {
  const bool bounded = max < INT64_MAX;
  const std::string range = bounded ? std::to_string(min) + ".." + std::to_string(max) : ">= " + std::to_string(min);
  return CLI::Validator(
      [min, max, range, bounded](std::string& text) {
        char* end = nullptr;
        errno = 0;
        const long long v = std::strtoll(text.c_str(), &end, 10);
        const bool whole = !text.empty() && end == text.c_str() + text.size() && errno == 0;
        return whole && v >= min && v <= max
                   ? std::string()
                   : std::string("needs a whole number ") + (bounded ? "in " : "") + range + ", got '" + text + "'";
      },
      range);
}

CLI::App* add_command(CLI::App& parent, const std::string& name, const std::string& summary) {
  CLI::App* cmd = parent.add_subcommand(name, summary);
  cmd->group("Commands");
  return cmd;
}

namespace {
std::atomic<bool> g_stop{false};
volatile std::sig_atomic_t g_stop_signal = 0;
volatile std::sig_atomic_t g_repeat_exits = 1;
// The first signal asks the work to stop cleanly (it polls the flag). A second one ends offline
// work at once, for work blocked where it cannot poll (a read from a pipe nobody writes: the
// handler's restarted system call would otherwise wait for ever); a bench run only says that
// its abort is under way (write(2): what a handler may call).
extern "C" void on_stop_signal(int sig) {
  if (g_stop.load()) {
    if (g_repeat_exits != 0) ::_exit(128 + sig);
    static const char kBusy[] =
        "hilbench: the abort is under way: the rig goes to its safe state and the run's record is written first "
        "(Ctrl-\\ kills at once, leaving the rig as it is and the run interrupted)\n";
    [[maybe_unused]] const ssize_t n = ::write(2, kBusy, sizeof kBusy - 1);
    return;
  }
  g_stop_signal = sig;
  g_stop.store(true);
}
}  // namespace

const std::atomic<bool>& StopSignal::install(Repeat repeat) {
  g_repeat_exits = repeat == Repeat::exits ? 1 : 0;
  std::signal(SIGINT, on_stop_signal);
  std::signal(SIGTERM, on_stop_signal);
  return g_stop;
}

const char* StopSignal::name() { return g_stop_signal == SIGTERM ? "SIGTERM" : "SIGINT"; }

int StopSignal::exit_code() { return 128 + (g_stop_signal == SIGTERM ? SIGTERM : SIGINT); }

}  // namespace hil::bench
