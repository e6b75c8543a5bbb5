// hilbench report RUN_DIR... [--out FILE] [--quiet]
#include <cmath>
#include <cstdio>

#include "cli.hpp"
#include "commands.hpp"
#include "hil/bench/run_report.hpp"

namespace hil::bench {

int cmd_report(const std::vector<std::string>& argv) {
  const Args args = parse_args(argv, {"out"}, {"quiet"});
  if (args.positional.empty()) throw UsageError("report needs at least one run folder");
  std::vector<std::filesystem::path> dirs(args.positional.begin(), args.positional.end());
  const std::filesystem::path out = args.option("out", (dirs.front() / "report.html").string());
  const auto runs = write_run_report(dirs, out);
  if (!args.has("quiet")) {
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

}  // namespace hil::bench
