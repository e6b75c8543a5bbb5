// hilbench report RUN_DIR... [--out FILE] [--quiet]
#include <cmath>
#include <cstdio>
#include <memory>

#include "commands.hpp"
#include "hil/bench/campaign/run_report.hpp"

namespace hil::bench {
namespace {

struct ReportArgs {
  std::vector<std::string> run_dirs;
  std::string out_file;  // empty: the first run folder's report.html
  bool quiet = false;
};

int run_report(const ReportArgs& args) {
  const std::vector<std::filesystem::path> dirs(args.run_dirs.begin(), args.run_dirs.end());
  const std::filesystem::path out = args.out_file.empty() ? dirs.front() / "report.html" : std::filesystem::path(args.out_file);
  const auto runs = write_run_report(dirs, out);
  if (!args.quiet) {
    std::printf("  %-28s %-11s %10s %12s %12s %10s\n", "run", "outcome", "IAE MPa.s", "stall s", "gap est deg", "touch chg");
    for (const auto& r : runs) {
      const auto& s = r.digest.summary;
      std::printf("  %-28s %-11s %10.4f %12s %12.3f %10ld\n", r.digest.name.c_str(), r.outcome.c_str(), s.iae_mpa_s,
                  std::isfinite(s.stall_s_total) ? std::to_string(s.stall_s_total).substr(0, 6).c_str() : "unknown",
                  s.gap_est_final_deg, s.touch_state_changes);
      if (!r.reason.empty()) std::printf("      %s\n", r.reason.c_str());
    }
    std::printf("  report: %s\n", out.c_str());
  }
  return 0;
}

}  // namespace

CommandRun define_report(CLI::App& cmd) {
  auto args = std::make_shared<ReportArgs>();
  cmd.add_option("runs", args->run_dirs, "run folders recorded by hilbench serve")
      ->required()
      ->type_name("RUN_DIR")
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  cmd.add_option("--out", args->out_file, "the report (default: the first RUN_DIR/report.html)")->type_name("FILE");
  cmd.add_flag("--quiet", args->quiet, "no table of the runs on stdout");
  return [args] { return run_report(*args); };
}

}  // namespace hil::bench
