// The hidden-effect suite, whole (issue 37, acceptance 1): draws the files from a seed, diagnoses
// each with the nominal model and every candidate, scores them and writes OUT/suite.md (the
// headline, per noise colour and level, per class, every file). tests/analysis/run_hidden_suite.sh
// builds and runs it; the light ctest is test_analysis_suite.
//
//   hil_hidden_suite [--seed N] [--singles N] [--pairs N] [--triples N] [--healthy-per-noise N]
//                    [--duration S] [--threads N] [--only NAME] [--out DIR] [--keep-files]
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <string>

#include "hidden_suite.hpp"

namespace {

int usage(const std::string& why) {
  std::fprintf(stderr,
               "hil_hidden_suite: %s\nusage: hil_hidden_suite [--seed N] [--singles N] [--pairs N] [--triples N] "
               "[--healthy-per-noise N] [--duration S] [--threads N] [--only NAME] [--out DIR] [--keep-files]\n",
               why.c_str());
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  namespace fs = std::filesystem;
  using namespace hil::test::suite;
  SuiteSpec spec;
  unsigned threads = 1;
  fs::path out = "out/hidden_suite";
  std::string only;
  bool keep = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--keep-files") {
      keep = true;
      continue;
    }
    if (i + 1 >= argc) return usage(a + " needs a value");
    const std::string v = argv[++i];
    try {
      if (a == "--seed")
        spec.seed = std::stoull(v);
      else if (a == "--singles")
        spec.singles = std::stoi(v);
      else if (a == "--pairs")
        spec.pairs = std::stoi(v);
      else if (a == "--triples")
        spec.triples = std::stoi(v);
      else if (a == "--healthy-per-noise")
        spec.healthy_per_noise = std::stoi(v);
      else if (a == "--duration")
        spec.duration_s = std::stod(v);
      else if (a == "--threads")
        threads = static_cast<unsigned>(std::stoul(v));
      else if (a == "--only")
        only = v;
      else if (a == "--out")
        out = v;
      else
        return usage("unknown option " + a);
    } catch (const std::exception&) {
      return usage(a + ": not a number: " + v);
    }
  }
  if (spec.duration_s < 10 || spec.duration_s > 600) return usage("--duration: 10 to 600 s");
  fs::create_directories(out / "files");
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<Score> scores;
  for (const SuiteFile& f : draw_suite(spec)) {
    if (!only.empty() && f.name != only) continue;
    try {
      scores.push_back(run_file(f, out / "files", threads));
    } catch (const std::exception& e) {  // a file the generator or diagnose failed on: scored as failed
      Score s;
      s.name = f.name;
      s.effects = f.effects_text();
      s.n_effects = static_cast<int>(f.hidden.size());
      s.colour = f.colour;
      s.level_kpa = f.level_kpa;
      s.verdict = std::string("error: ") + e.what();
      scores.push_back(s);
    }
    const Score& s = scores.back();
    std::printf("%-28s %-20s %-5s enc %-3s %-11s %-15s %.1f kPa: %-16s found %-40s %s %s (%.1f s)\n", s.name.c_str(),
                s.effects.c_str(), s.logger.c_str(), s.encoder ? "yes" : "no", s.reference.c_str(), s.colour.c_str(), s.level_kpa,
                s.verdict.c_str(), s.found.empty() ? "-" : s.found.c_str(),
                s.n_effects == 0  ? (s.pass ? "no alarm" : "FALSE ALARM")
                : !s.identifiable ? "not identifiable"
                : s.pass          ? "found"
                                  : "MISSED",
                s.params.c_str(), s.wall_s);
    std::fflush(stdout);
    if (!keep) fs::remove(out / "files" / (f.name + ".csv"));
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const std::string md = markdown(scores, spec, wall);
  std::ofstream(out / "suite.md") << md;
  std::printf("\n%s", md.c_str());
  return 0;
}
