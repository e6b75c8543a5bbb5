// hilbench: one executable, one sub-command per job. The command line is built here, once, on
// CLI11, and every error becomes its exit code here: 2 for a bad invocation, 1 for a bad
// configuration or measurement file or a failed job.
#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include "cli.hpp"
#include "commands.hpp"
#include "hil/config.hpp"
#include "hil/csv_reader.hpp"

namespace {

using hil::bench::CommandRun;

struct Command {
  const char* name;
  const char* summary;  // its one line in `hilbench --help`
  CommandRun (*define)(CLI::App&);
};

const Command kCommands[] = {
    {"sim", "run a campaign on the simulated plant, faster than real time", hil::bench::define_sim},
    {"run", "run a campaign on a rig without the server, recorded as hilbench serve records it", hil::bench::define_run},
    {"sweep", "run a campaign over a grid or distribution of conditions, on every core or on Slurm; robustness maps",
     hil::bench::define_sweep},
    {"effects", "list the physical effects a plant file may use, with their parameters", hil::bench::define_effects},
    {"compensators", "list the compensators a campaign may use, with their parameters", hil::bench::define_compensators},
    {"serve", "the bench server: real-time loop, operator API (HTTP/JSON, WebSocket telemetry)", hil::bench::define_serve},
    {"ctl", "command-line client of hilbench serve", hil::bench::define_ctl},
    {"compare", "replay a measurement through a model and show where the model fails", hil::bench::define_compare},
    {"diagnose", "find the missing physical effect of a model from measurements", hil::bench::define_diagnose},
    {"plant", "the simulator side of the HIL: the plant in real time behind emulated CAN and Modbus devices",
     hil::bench::define_plant},
    {"report", "the paper-style report of runs recorded by hilbench serve", hil::bench::define_report},
    {"drive", "know the rig's CiA 402 drive before a run, without moving it", hil::bench::define_drive},
    {"characterise", "the observers on the paper's scenarios, noise-free and noisy, as a markdown table",
     hil::bench::define_characterise},
};

// Usage lines in the house style, "usage: hilbench compare --model MODEL.yaml --data FILE.csv [options]":
// what must be given spelled out, everything optional behind [options].
class Formatter : public CLI::Formatter {
 public:
  std::string make_usage(const CLI::App* app, std::string name) const override {
    std::string usage = "usage: " + name;
    bool optional = false;
    for (const CLI::Option* o : app->get_options([](const CLI::Option* o) { return o->nonpositional(); })) {
      if (o->get_required()) {
        usage += " " + o->get_name() + " " + o->get_type_name();
      } else {
        optional = true;
      }
    }
    for (const CLI::Option* o : app->get_options([](const CLI::Option* o) { return o->get_positional(); })) {
      const std::string p = o->get_type_name() + (o->get_items_expected_max() > 1 ? "..." : "");
      usage += " " + (o->get_required() ? p : "[" + p + "]");
    }
    if (!app->get_subcommands({}).empty()) usage += " COMMAND";
    if (optional) usage += " [options]";
    return usage + "\n";
  }
};

// The sub-command the command line reached (the root when none) and its path ("hilbench ctl start").
const CLI::App* reached(const CLI::App& root, std::string& path) {
  const CLI::App* at = &root;
  path = root.get_name();
  for (auto subs = at->get_subcommands(); !subs.empty(); subs = at->get_subcommands()) {
    at = subs.front();
    path += " " + at->get_name();
  }
  return at;
}

// The first argument that nothing took, worded with a suggestion: "unknown option --outt (did you
// mean --out?)", "unknown command 'prboe' (did you mean 'probe'?)"; empty when every one was taken.
// An option falls through from a sub-command to its parent, so the parent's names count too.
std::string unknown_argument(const CLI::App* at) {
  std::vector<std::string> options, commands;
  for (const CLI::App* a = at; a != nullptr; a = a->get_parent()) {
    for (const CLI::Option* o : a->get_options()) {
      for (const auto& n : o->get_lnames()) options.push_back("--" + n);
    }
    if (!a->get_fallthrough()) break;
  }
  for (const CLI::App* s : at->get_subcommands({})) commands.push_back(s->get_name());
  for (const CLI::App* a = at; a != nullptr; a = a->get_parent()) {
    for (const std::string& arg : a->remaining()) {
      if (arg.size() > 1 && arg[0] == '-') {
        const std::string name = arg.substr(0, arg.find('='));
        const std::string hint = hil::cfg::closest(name, options);
        return "unknown option " + name + (hint.empty() ? "" : " (did you mean " + hint + "?)");
      }
      if (!commands.empty()) {
        const std::string hint = hil::cfg::closest(arg, commands);
        return "unknown command '" + arg + "'" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)");
      }
      return "unexpected argument '" + arg + "'";
    }
  }
  return "";
}

// What a RequiredError is about, with the value's kind: "--data FILE.csv is required".
std::string missing_requirement(const CLI::App* at) {
  for (const CLI::App* a = at; a != nullptr; a = a->get_parent()) {
    for (const CLI::Option* o : a->get_options()) {
      if (!o->get_required() || o->count() > 0) continue;
      return o->get_positional() ? "needs " + o->get_type_name() : o->get_name() + " " + o->get_type_name() + " is required";
    }
  }
  if (at->get_require_subcommand_min() > 0) {
    std::string names;
    for (const CLI::App* s : at->get_subcommands({})) names += (names.empty() ? "" : ", ") + s->get_name();
    return "needs a command: " + names;
  }
  return "";
}

// A bad invocation: what is wrong, naming the option, then the usage; exit code 2.
int usage_error(const Formatter& formatter, const CLI::App& root, const std::string& message) {
  std::string path;
  const CLI::App* at = reached(root, path);
  std::cerr << path << ": " << message << "\n"
            << formatter.make_usage(at, path) << "(" << path << " --help lists every option)\n";
  return 2;
}

int parse_error(const Formatter& formatter, const CLI::App& root, const CLI::Error& e) {
  std::string path;
  const CLI::App* at = reached(root, path);
  // An unknown option first: it is often why a required one looks missing (--modle for --model).
  std::string message = unknown_argument(at);
  if (message.empty() && dynamic_cast<const CLI::RequiredError*>(&e) != nullptr) message = missing_requirement(at);
  if (message.empty() && dynamic_cast<const CLI::ArgumentMismatch*>(&e) != nullptr) {
    const std::string what = e.what();  // "--out: 1 required DIR missing"
    if (what.rfind("--", 0) == 0) message = what.substr(0, what.find(':')) + " needs a value";
  }
  return usage_error(formatter, root, message.empty() ? e.what() : message);
}

// Every command logs through spdlog, at the level --log-level names. The server keeps spdlog's
// own logger (standard output, a time stamp and a level on each line: a long-lived process whose
// log is read afterwards) and the plant simulator logs the same way on the standard error. The
// other commands are short jobs whose warnings already say who speaks ("sweep NAME: ..."): a
// plain line on the standard error, as before. Progress lines are not log lines
// (hil/progress_line.hpp); a command's final error is its result and main prints it below.
void set_up_logging(const std::string& command, const std::string& level_name) {
  if (command != "serve") {
    auto logger = spdlog::stderr_color_mt("hilbench");
    if (command != "plant") logger->set_pattern("%v");
    spdlog::set_default_logger(logger);
  }
  spdlog::set_level(spdlog::level::from_str(level_name));
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("hilbench: the hardware-in-the-loop bench, one sub-command per job", "hilbench");
  // Sub-commands copy these when they are added: the formatter, and the last of an option given
  // twice counts (test harnesses and wrappers append their overrides to a default command line).
  const auto formatter = std::make_shared<Formatter>();
  formatter->column_width(32);
  app.formatter(formatter);
  app.option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
  app.set_version_flag("--version", std::string("hilbench ") + HIL_VERSION);
  app.require_subcommand(1);
  std::string log_level = "info";
  app.add_option("--log-level", log_level, "the least severe log line shown, for every command: debug, info, warn, error or off")
      ->type_name("LEVEL")
      ->check(CLI::IsMember({"debug", "info", "warn", "error", "off"}));
  std::vector<std::string> names;
  std::vector<std::pair<const CLI::App*, CommandRun>> runs;
  for (const auto& c : kCommands) {
    CLI::App* cmd = hil::bench::add_command(app, c.name, c.summary);
    runs.emplace_back(cmd, c.define(*cmd));
    names.emplace_back(c.name);
  }

  if (argc < 2) {
    std::cerr << app.help();
    return 2;
  }
  if (const std::string first = argv[1]; first[0] != '-' && std::find(names.begin(), names.end(), first) == names.end()) {
    const std::string hint = hil::cfg::closest(first, names);
    std::cerr << "hilbench: unknown command '" << first << "'" << (hint.empty() ? "" : " (did you mean '" + hint + "'?)")
              << "\n\n"
              << app.help();
    return 2;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForVersion& e) {
    std::cout << e.what() << "\n";
    return 0;
  } catch (const CLI::CallForHelp&) {
    std::cout << app.help();
    return 0;
  } catch (const CLI::Error& e) {
    return parse_error(*formatter, app, e);
  }

  const CLI::App* cmd = app.get_subcommands().front();
  const std::string where = "hilbench " + cmd->get_name();
  set_up_logging(cmd->get_name(), log_level);
  for (const auto& [app_of, run] : runs) {
    if (app_of != cmd) continue;
    try {
      const int rc = run();
      // What a command printed is its result (a table, a summary, JSON): a full disk or a closed
      // pipe that took none of it is a failure, not rc 0 with an empty file.
      errno = 0;
      std::cout.flush();
      if (std::fflush(stdout) != 0 || std::ferror(stdout) || !std::cout) {
        const int e = errno;  // 0 when the failed write was earlier and its reason is gone
        std::cerr << where << ": error: cannot write the standard output" << (e != 0 ? std::string(": ") + std::strerror(e) : "")
                  << "\n";
        return rc != 0 ? rc : 1;
      }
      return rc;
    } catch (const hil::bench::UsageError& e) {
      return usage_error(*formatter, app, e.what());
    } catch (const hil::cfg::Error& e) {
      std::cerr << where << ": " << e.what() << "\n";
      return 1;
    } catch (const hil::CsvError& e) {
      std::cerr << where << ": " << e.what() << "\n";
      return 1;
    } catch (const std::filesystem::filesystem_error& e) {
      // The path first, as every other error here names where: "DIR: Not a directory (cannot
      // create directories)". libstdc++'s what() is "filesystem error: OP: REASON [P1] [P2]".
      const std::string what = e.what(), reason = e.code().message(), head = "filesystem error: ";
      const auto op_end = what.find(": " + reason);
      const std::string op = what.rfind(head, 0) == 0 && op_end != std::string::npos && op_end > head.size()
                                 ? what.substr(head.size(), op_end - head.size())
                                 : "";
      std::cerr << where << ": error: " << e.path1().string() << ": " << reason;
      if (!op.empty()) std::cerr << " (" << op << (e.path2().empty() ? "" : " to " + e.path2().string()) << ")";
      std::cerr << "\n";
      return 1;
    } catch (const std::exception& e) {
      std::cerr << where << ": error: " << e.what() << "\n";
      return 1;
    }
  }
  return 2;  // unreachable: every sub-command has its job
}
