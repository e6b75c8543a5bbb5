// A hidden-effect suite drawn from a seed (issue 37, acceptance 1): measurement files with none,
// one, two or three hidden effects, on a real transducer's coloured noise, and how diagnose scores
// on them. Made with the scenarios' own helpers (scenarios.hpp: the closed-loop campaign run, the
// other lab's logger, add_sensor_noise), never with a simulator of its own.
//
// A file's draw: the effects from the registered candidates (each with a magnitude range, checked
// against the candidate's fit prior: its search range holds the truth, its neutral value is the
// "no change" the tolerance counts from), a reference (random walk, PRBS, a throttling mission),
// a logger (the bench's closed-loop telemetry, with or without the encoder; or a DAQ: open loop,
// absolute time stamps, jittered rows, holes, text columns, CRLF, ADC steps) and a noise colour and
// level (AR(1) phi 0.3-0.8 or a first-order anti-alias filter at 50-200 Hz; 1-5 kPa).
//
// Scoring: a file with effects is *found in full* when diagnose adds exactly the hidden candidates
// and every hidden parameter is within 15 % of its truth; a healthy file passes when diagnose
// says nothing_missing and adds nothing. A combination is *identifiable* when no pair in it is
// one analysis/README.md (Limits) names as not told apart from pressure, and dropping any one of
// its effects from the true model costs at least half the noise power (measured on the file).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "hil/analysis/diagnose.hpp"
#include "hil/analysis/measurement.hpp"
#include "hil/plant/plant.hpp"
#include "scenarios.hpp"

namespace hil::test::suite {

// One hidden effect with its truth: the candidate diagnose must add and one parameter of it.
struct Hidden {
  std::string tag;        // short name in file names ("gap", "lag", ...)
  std::string candidate;  // diagnose's name (the fit prior's candidate)
  std::string key;        // the parameter scored
  double value = 0;       // its truth
  double neutral = 0;     // its "no change" value in the nominal model (the prior's neutral)
};

enum class Reference { random_walk, prbs, mission };
enum class Logger { bench, daq };

struct SuiteFile {
  std::string name;
  std::uint64_t seed = 1;
  std::vector<Hidden> hidden;  // empty: a healthy file
  Reference reference = Reference::random_walk;
  Logger logger = Logger::bench;
  bool encoder = false;
  std::string compensation = "none";  // bench logger: none | constant | adaptive
  double duration_s = 30;
  SensorNoise noise;
  std::string colour;    // "AR(1) phi 0.55", "filter 100 Hz"
  double level_kpa = 0;  // the coloured part's RMS
  // The nominal plant with the hidden effects (without one of them: `except` its index).
  plant::Plant truth(const plant::Plant& nominal, int except = -1) const;
  std::string effects_text() const;  // "gap+lag", "none"
};

struct SuiteSpec {
  std::uint64_t seed = 37;
  int healthy_per_noise = 1;  // healthy files per noise colour and level (every one of the grid)
  int singles = 8, pairs = 8, triples = 8;
  double duration_s = 30;
  double daq_share = 0.25;  // of the files, through the DAQ
};

// The noise colours and levels of the suite (every healthy file's grid).
std::vector<std::string> colours();
std::vector<double> levels_kpa();

std::vector<SuiteFile> draw_suite(const SuiteSpec& spec);
// One file as the suite draws it, with the effects, colour, level and logger given (the light
// test's picks); the rest (reference, encoder, compensation, magnitudes) drawn from `seed`.
SuiteFile draw_file(std::uint64_t seed, const std::string& name, const std::vector<std::string>& tags, const std::string& colour,
                    double level_kpa, Logger logger, double duration_s = 30);
// Writes DIR/<name>.csv (noise-free, then the transducer's noise added).
std::filesystem::path write_file(const SuiteFile& f, const std::filesystem::path& dir);

struct Score {
  std::string name, effects, colour, reference, logger, verdict;
  double level_kpa = 0;
  int n_effects = 0;
  bool encoder = false;
  bool identifiable = true;  // healthy files: true
  std::string why_not_identifiable;
  bool pass = false;         // found in full / healthy: nothing_missing with nothing added
  bool right_set = false;    // the added candidates are the hidden ones
  std::string found;         // the added candidates, "+"-joined
  std::string params;        // "gap_deg 1.598 (truth 1.6, -0.1 %)" ...
  double worst_error = 0;    // the largest |fitted - truth| / |truth| over the hidden parameters
  double min_drop_cost = 0;  // the smallest cost of dropping one hidden effect, in noise powers
  double fit_before_pct = 0, fit_after_pct = 0, floor_pct = 0, wall_s = 0;
};

// Scores a diagnosis of `f` (written and read back as `m`).
Score score(const SuiteFile& f, const analysis::Measurement& m, const analysis::Diagnosis& d);
// Writes the file, diagnoses it (the nominal model, every candidate) and scores it.
Score run_file(const SuiteFile& f, const std::filesystem::path& dir, unsigned threads = 0);

// The results as Markdown: the headline (hit rate over identifiable combinations, false alarms),
// per noise colour and level, per class (effects), and every file's line.
std::string markdown(const std::vector<Score>& scores, const SuiteSpec& spec, double wall_s);

}  // namespace hil::test::suite
