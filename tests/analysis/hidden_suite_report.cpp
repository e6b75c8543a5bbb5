// The hidden-effect suite's results in words and tables (hidden_suite.hpp markdown()).
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "hidden_suite.hpp"

namespace hil::test::suite {
namespace {

std::string f1(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1f", v);
  return b;
}
std::string f2(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.2f", v);
  return b;
}

struct Tally {
  int n = 0, pass = 0;
  std::string cell() const { return n == 0 ? "-" : std::to_string(pass) + "/" + std::to_string(n); }
};

}  // namespace

std::string markdown(const std::vector<Score>& scores, const SuiteSpec& spec, double wall_s) {
  Tally healthy, identifiable, all_effects;
  int not_identifiable = 0;
  std::map<std::pair<std::string, double>, Tally> alarms, hits;  // per colour and level
  std::map<std::string, Tally> classes;                          // per effect combination (identifiable)
  std::map<int, Tally> by_count;
  for (const auto& s : scores) {
    const auto key = std::pair{s.colour, s.level_kpa};
    if (s.n_effects == 0) {
      ++healthy.n, healthy.pass += s.pass;
      ++alarms[key].n, alarms[key].pass += s.pass;  // pass: no alarm
      continue;
    }
    ++all_effects.n, all_effects.pass += s.pass;
    if (!s.identifiable) {
      ++not_identifiable;
      continue;
    }
    ++identifiable.n, identifiable.pass += s.pass;
    ++hits[key].n, hits[key].pass += s.pass;
    ++classes[s.effects].n, classes[s.effects].pass += s.pass;
    ++by_count[s.n_effects].n, by_count[s.n_effects].pass += s.pass;
  }
  std::string o;
  o += "Seed " + std::to_string(spec.seed) + ", " + std::to_string(scores.size()) + " files of " + f1(spec.duration_s) +
       " s at 1 kHz: " + std::to_string(healthy.n) + " healthy (every colour at every level), " + std::to_string(all_effects.n) +
       " with effects (" + std::to_string(spec.singles) + " with one, " + std::to_string(spec.pairs) + " with two, " +
       std::to_string(spec.triples) + " with three); wall " + f1(wall_s) + " s.\n\n";
  const double rate = identifiable.n ? 100.0 * identifiable.pass / identifiable.n : 0.0;
  o += "- **Found in full** (the hidden candidates exactly, each parameter within 15 %): " + identifiable.cell() +
       " identifiable combinations (" + f1(rate) + " %); one effect " + by_count[1].cell() + ", two " + by_count[2].cell() +
       ", three " + by_count[3].cell() + ". Not identifiable (not scored): " + std::to_string(not_identifiable) + ".\n";
  o += "- **False alarms** (a healthy file not `nothing_missing`, or anything added): " +
       std::to_string(healthy.n - healthy.pass) + " of " + std::to_string(healthy.n) + ".\n\n";
  // Per colour and level: healthy files passing (no alarm), identifiable files found in full.
  std::vector<std::string> cols = colours();
  std::vector<double> lvls = levels_kpa();
  o += "| noise | ";
  for (double l : lvls) o += f1(l) + " kPa: no alarm | " + f1(l) + " kPa: found | ";
  o += "\n|---|";
  for (std::size_t i = 0; i < lvls.size(); ++i) o += "---|---|";
  o += "\n";
  for (const auto& c : cols) {
    o += "| " + c + " | ";
    for (double l : lvls) o += alarms[{c, l}].cell() + " | " + hits[{c, l}].cell() + " | ";
    o += "\n";
  }
  o += "\n| class (identifiable) | found in full |\n|---|---|\n";
  for (const auto& [name, t] : classes) o += "| " + name + " | " + t.cell() + " |\n";
  o += "\n| file | effects | logger | encoder | reference | noise | verdict | found | fit before / after / floor % | "
       "drop cost | result | s |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& s : scores) {
    const std::string result = s.n_effects == 0  ? (s.pass ? "no alarm" : "FALSE ALARM")
                               : !s.identifiable ? "not identifiable: " + s.why_not_identifiable
                               : s.pass          ? "found"
                                                 : "MISSED";
    o += "| " + s.name + " | " + s.effects + " | " + s.logger + " | " + (s.encoder ? "yes" : "no") + " | " + s.reference + " | " +
         s.colour + ", " + f1(s.level_kpa) + " kPa | " + s.verdict + " | " + (s.found.empty() ? "-" : s.found) + " | " +
         f2(s.fit_before_pct) + " / " + f2(s.fit_after_pct) + " / " + f2(s.floor_pct) + " | " +
         (s.n_effects ? f1(s.min_drop_cost) : std::string("-")) + " | " + result +
         (s.params.empty() ? "" : " (" + s.params + ")") + " | " + f1(s.wall_s) + " |\n";
  }
  return o;
}

}  // namespace hil::test::suite
