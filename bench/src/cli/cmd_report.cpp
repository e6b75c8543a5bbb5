// hilbench report RUN_DIR... [--out FILE] [--quiet]
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

#include <spdlog/spdlog.h>

#include "commands.hpp"
#include "hil/bench/campaign/run_report.hpp"
#include "hil/bench/server/runner.hpp"
#include "hil/output_path.hpp"
#include "hil/progress_line.hpp"
#include "hil/report/report.hpp"

namespace hil::bench {
namespace {

struct ReportArgs {
  std::vector<std::string> run_dirs;
  std::string out_file;  // empty: the first run folder's report.html
  bool quiet = false;
};

// --out must not replace a file of a run the report reads (RUN/run.json made the run unreadable):
// every file in the run folders is an input, but for a folder's own report.html, which a report
// of the run replaces. Said before the reading, which takes a while.
void check_report_output(const std::vector<std::filesystem::path>& run_dirs, const std::filesystem::path& out_file) {
  std::vector<std::filesystem::path> inputs;
  for (const auto& dir : run_dirs) {
    std::error_code ec;
    const auto own_report = dir / "report.html";
    for (auto it = std::filesystem::recursive_directory_iterator(dir, ec); !ec && it != std::filesystem::end(it);
         it.increment(ec)) {
      std::error_code type_ec;
      if (it->is_directory(type_ec) || it->path() == own_report) continue;
      inputs.push_back(it->path());
    }
  }
  check_output_file("--out", out_file, inputs, "the report", report::kGeneratorTag);
}

int run_report(const ReportArgs& args) {
  const std::vector<std::filesystem::path> dirs(args.run_dirs.begin(), args.run_dirs.end());
  const std::filesystem::path out = args.out_file.empty() ? dirs.front() / "report.html" : std::filesystem::path(args.out_file);
  check_report_output(dirs, out);
  // A run whose process was killed (its run.json still "running", no live process holding its
  // lock) gets its honest end before it is reported.
  for (const auto& dir : dirs) {
    if (mark_interrupted_run(dir, "hilbench report"))
      spdlog::warn("run {}: its process ended during the run; marked interrupted", dir.filename().string());
  }
  RunReportOptions options;
  // SIGINT/SIGTERM: the reading stops at its next chunk of rows and nothing is written.
  options.cancel = &StopSignal::install();
  // Progress on stderr once the reading takes a while (an hour's run at 1 kHz: a few seconds).
  std::optional<ProgressLine> line;
  if (!args.quiet) {
    ProgressLine::Options po;
    po.delay_s = 1;
    line.emplace("report", po);
    options.progress = [&](double f) { line->update(f, [] { return std::string("of the telemetry read"); }); };
  }
  std::vector<RecordedRun> runs;
  try {
    runs = write_run_report(dirs, out, options);
  } catch (const Cancelled&) {
    if (line) line->end();
    spdlog::warn("report: cancelled by {}; nothing was written to {}", StopSignal::name(), out.string());
    return StopSignal::exit_code();
  }
  if (line) line->end();
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
  cmd.add_option("runs", args->run_dirs, "run folders recorded by hilbench serve or hilbench run")
      ->required()
      ->type_name("RUN_DIR")
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  cmd.add_option("--out", args->out_file, "the report (default: the first RUN_DIR/report.html)")
      ->type_name("FILE")
      ->check(path_value());
  cmd.add_flag("--quiet", args->quiet, "no table of the runs on stdout");
  return [args] { return run_report(*args); };
}

}  // namespace hil::bench
