// hilbench characterise [--readme FILE] [--campaigns DIR]: the observers and compensators on the paper's scenarios,
// noise-free and with the nominal transducer, as one markdown table. With --readme, the table
// replaces the block between the characterise markers in FILE (the README's table is made so).
#include <cstdio>
#include <memory>
#include <sstream>

#include "commands.hpp"
#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/campaign/sim.hpp"
#include "hil/line_file.hpp"
#include "hil/text_file.hpp"

namespace hil::bench {
namespace {

constexpr const char* kBegin = "<!-- characterise:begin -->";
constexpr const char* kEnd = "<!-- characterise:end -->";

// Mean stall over the reversals whose window is at least 1 s (the last one of 18 s is shorter).
double mean_stall(const Campaign& c, const RunSummary& s) {
  double sum = 0;
  int n = 0;
  for (std::size_t i = 0; i < s.reversals.size(); ++i) {
    const double next = i + 1 < s.reversals.size() ? s.reversals[i + 1].t_s : c.duration_s;
    if (next - s.reversals[i].t_s < 1.0) continue;
    sum += s.reversals[i].stall_s;
    ++n;
  }
  return n ? sum / n : 0;
}

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

}  // namespace

std::string characterise_table(const std::filesystem::path& campaigns_dir) {
  std::ostringstream t;
  t << "| scenario | sensor noise | run | compensation | observer | IAE [MPa s] | stall per reversal [s] | "
       "stall vs none | touch changes per reversal | jumps | gap estimate at end [deg] (true) |\n"
    << "|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const char* name : {"paper_constant", "paper_adaptive", "gap_shrink"}) {
    for (double noise_kpa : {0.0, 2.0}) {
      const Campaign c = with_sensor_noise(load_campaign(campaigns_dir / (std::string(name) + ".yaml")), noise_kpa);
      double none_stall = 0;
      for (const auto& run : c.runs) {
        const RunSummary s = summarise_run(c, run);
        const double stall = mean_stall(c, s);
        if (run.controller.compensation == ctl::Compensation::none) none_stall = stall;
        const char* comp = ctl::compensation_name(run.controller.compensation);
        const bool baseline = run.controller.compensation == ctl::Compensation::none;
        t << "| " << name << " | " << fmt("%g kPa", noise_kpa) << " | " << run.name << " | " << comp << " | "
          << (baseline ? "-" : run.controller.compensator) << " | " << fmt("%.3f", s.iae_mpa_s) << " | " << fmt("%.3f", stall)
          << " | " << (baseline || none_stall <= 0 ? std::string("-") : fmt("%.0f %%", 100 * stall / none_stall)) << " | "
          << fmt("%.1f", s.reversals.empty() ? 0.0 : double(s.touch_state_changes) / s.reversals.size()) << " | "
          << s.compensation_events << " | "
          << (baseline ? std::string("-") : fmt("%.2f", s.gap_est_final_deg) + fmt(" (%.2f)", s.gap_true_final_deg)) << " |\n";
      }
    }
  }
  return t.str();
}

namespace {

struct CharacteriseArgs {
  std::string readme;  // empty: the table goes to stdout
  std::string campaigns_dir = "configs/campaigns";
};

int run_characterise(const CharacteriseArgs& args) {
  const std::string table = characterise_table(args.campaigns_dir);
  if (args.readme.empty()) {
    std::fputs(table.c_str(), stdout);
    return 0;
  }
  // A README that is a link is updated where it lives (the link stays a link).
  std::filesystem::path readme = args.readme;
  if (std::filesystem::is_symlink(readme)) readme = std::filesystem::canonical(readme);
  std::string text = hil::read_text_file(readme, "a README");
  const auto b = text.find(kBegin), e = text.find(kEnd);
  if (b == std::string::npos || e == std::string::npos || e < b) {
    throw std::runtime_error(readme.string() + ": no '" + kBegin + "' ... '" + kEnd + "' block to replace");
  }
  text.replace(b, e - b, std::string(kBegin) + "\n" + table);
  hil::replace_file(readme, text);  // whole or not at all: a full disk never leaves a cut README
  std::printf("updated the table in %s\n", readme.c_str());
  return 0;
}

}  // namespace

CommandRun define_characterise(CLI::App& cmd) {
  auto args = std::make_shared<CharacteriseArgs>();
  cmd.add_option("--readme", args->readme, "replace the table between the characterise markers in FILE")
      ->type_name("FILE")
      ->check(path_value());
  cmd.add_option("--campaigns", args->campaigns_dir, "the folder of the paper's campaigns")
      ->type_name("DIR")
      ->capture_default_str();
  return [args] { return run_characterise(*args); };
}

}  // namespace hil::bench
