// `hilbench diagnose`: which missing physical effect explains the misfit? Each candidate
// (candidates.hpp) is fitted to the data and ranked by an information criterion that makes
// every extra parameter earn its place; the best one that earns it is added to the model, and
// the search repeats until nothing more earns its place (greedy forward selection).
//
// Criterion (per round, against the current model, N rows; src/criterion.hpp): the residual is
// whitened by the measurement noise's own model (noise_model.hpp: coloured plus white noise,
// estimated from the data), W its sum of squares, and
//   dBIC = N * ln(W_candidate / W_model) + k * ln(N)
// with k the candidate's free parameters: every row counts, the noise's correlation being taken
// out by the filter (an effective sample size from the residual's own correlation collapsed while
// a slow misfit remained). A candidate earns its place when
//   dBIC < -10  (very strong evidence), and
//   it removes >= 25 % of the model's excess error power (RSS_model - N sigma^2, sigma the
//   measurement noise's total RMS), and at least 5 % of N sigma^2 (a real improvement, not noise
//   fitting).
// When the best single effect of the first round does not reach the noise floor, the search also
// follows the next two first choices that earn their place (a beam of three paths, each greedy
// after its first step) and keeps the path with the lowest BIC: a two-effect misfit is often
// mimicked best by a third effect alone. From round 2 on, the top candidates are refitted jointly
// with every accepted effect (nothing frozen) and judged on that joint fit; when the search stops, a forward-backward revisit drops an effect the others
// make redundant or swaps it for one that gives a lower BIC, and when that or a revised form
// changed the model above the noise floor, the search goes forward again (analysis/README.md,
// Selection).
// Offline code: allocates, throws, and uses up to `threads` worker threads.
#pragma once

#include <cmath>
#include <filesystem>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "hil/analysis/cancel.hpp"
#include "hil/analysis/candidates.hpp"
#include "hil/analysis/measurement.hpp"
#include "hil/analysis/residuals.hpp"
#include "hil/plant/plant.hpp"

namespace hil::analysis {

struct FittedParam {
  std::string effect{}, key{};
  double value = 0;
  double sigma = 0;        // 1-sigma; NaN when not computed (grid-searched step times)
  double model_value = 0;  // in the model before the fit (NaN: the block is new)
  bool grid = false;       // searched on a grid (discontinuous)
  // Several files: an event time (a step) belongs to one file: its index here, and `value` counts
  // from that file's first row (-1: a parameter all files share).
  int file = -1;
  // A grid parameter of an added effect (a step time): the lowest and highest grid values that
  // fit within one standard error of the best, the others refitted (diagnose.cpp grid_span). A
  // step is placed only between the motions around it; this says where. NaN otherwise.
  double lo = std::numeric_limits<double>::quiet_NaN(), hi = std::numeric_limits<double>::quiet_NaN();
  bool located_between() const { return std::isfinite(lo) && std::isfinite(hi) && hi > lo; }
  std::string span_text() const;  // " [lo to hi fit as well]", or empty
  // The range the candidate searches this parameter in (candidates.hpp FreeParam::lo/hi; NaN for a
  // grid parameter). A value at an end of it is no measurement: the data wanted a value beyond
  // what the candidate allows (a sensor gain of 2.0, a burn rate at twice the nominal on a file
  // logged in bar), so the effect likely stands in for something else.
  double search_lo = std::numeric_limits<double>::quiet_NaN(), search_hi = std::numeric_limits<double>::quiet_NaN();
  bool at_search_limit() const;
  std::string limit_text() const;  // " (at the end of its search range, LO to HI: ...)", or empty
  // What the nominal plant makes credible (candidates.hpp FreeParam::credible_*; NaN: no bound).
  double credible_lo = std::numeric_limits<double>::quiet_NaN(), credible_hi = std::numeric_limits<double>::quiet_NaN();
  std::string credible_why{};
  bool implausible() const { return std::isfinite(value) && (value < credible_lo || value > credible_hi); }
  std::string plausibility_text() const;  // " (implausible: beyond ...)", or empty
};

struct CandidateResult {
  std::string effect, variant, description;
  std::vector<FittedParam> parameters;
  double rss_pa2 = 0;
  double fit_before_pct = 0, fit_after_pct = 0;
  double excess_explained = 0;  // share of the model's excess error power this candidate removes
  double delta_bic = 0;
  std::size_t k = 0;  // free parameters counted by the criterion
  bool earns_place = false;
  bool refined = false;  // the final fit ran on every row (not only on the decimated copy)
  std::string why_not;   // when it does not earn its place: which test failed
  int evaluations = 0;   // replays spent
};

struct Round {
  double rss_before_pa2 = 0, fit_before_pct = 0;
  double whitened_rss_before = 0;        // the criterion's: the residual whitened by the noise model
  std::vector<CandidateResult> ranking;  // best first (lowest dBIC)
  std::string added;                     // empty: nothing earned its place
  // Why the round did not fit candidates (ranking empty), or how it chose differently from the
  // ranking (a pair rescue, a revisit).
  std::string note;
};

// One path of the search (a first choice followed greedily), for the report.
struct Alternative {
  std::vector<std::string> effects;
  double fit_pct = 0;
  double bic = 0;  // relative to the chosen path (0 for it)
  bool chosen = false;
};

// Correlation of two fitted parameters of different effects in the final joint fit. Near +-1 a
// change of one can be largely undone by the other; the file cannot tell the two effects apart
// when, in addition, the fit cannot pin them: a 1-sigma uncertainty above kUnpinnedShare of the
// change from the model's value, or of the parameter's typical size when it hardly moved (a
// correlation of 0.998 with both known to 1 % is separated).
struct ParamCorrelation {
  std::string effect_a, key_a, effect_b, key_b;
  double rho = 0;
  bool indistinguishable = false;
};
inline constexpr double kReportCorrelation = 0.5;  // listed from here on
inline constexpr double kIndistinguishableCorrelation = 0.95;
inline constexpr double kUnpinnedShare = 0.1;

// An explanation the file does not tell from the one found: `alternative` (its `variant`) in
// place of the found `effect`, the other found effects refitted, gives a whole-model BIC within
// kRivalBic of the found model's (`dbic`: its BIC minus the found one's) and fits `fit_pct`.
struct Rival {
  std::string effect, alternative, variant;
  double dbic = 0, fit_pct = 0;
};
inline constexpr double kRivalBic = 10;  // the criterion's own margin (an effect earns its place below -10)

struct NotIdentifiable {
  std::string effect, reason;
};

// One measurement file of a diagnosis (several: diagnose --data a --data b, files of one rig).
struct FileFit {
  std::size_t rows = 0;
  double time_origin_s = 0;  // file time of its row 0: the fitted model's t = 0 for it
  // Of several acquisitions appended in one file: which (1, 2, ...; 0: the file holds one) and the
  // file line of its first row.
  std::size_t acquisition = 0, first_line = 0;
  ResidualReport before, after;
};

struct Diagnosis {
  std::size_t rows = 0;  // all files together
  bool has_encoder = false;
  std::size_t decimation = 1;  // rows per row of the copy the coarse fits ran on
  double time_origin_s = 0;    // file time of row 0: the fitted model's t = 0 (replay.hpp)
  // Over all files (one file: equal to before/after): the noise is the files' pooled sigma
  // (N sigma^2 = sum of N_i sigma_i^2), the spread pooled about each file's own mean.
  double noise_sigma_pa = 0, noise_floor_fit_pct = 0;
  double fit_before_pct = 0, fit_after_pct = 0, rmse_before_pa = 0, rmse_after_pa = 0;
  // Every file's own comparison; `before` and `after` below are the first file's. With several
  // files every fitted parameter is shared by all of them (one rig): a gap, an offset, a lag, a
  // rate; time-dependent ones (a step time, erosion, a drift) count from each file's first row.
  std::vector<FileFit> files;
  std::vector<Round> rounds;
  std::vector<CandidateResult> added;          // in the order found, values after the joint refit
  bool explained = false;                      // an effect earned its place, and no stand-in (README, Verdict)
  bool at_noise_floor = false;                 // the final model's RMSE is within 10 % of the noise
  std::string verdict;                         // explained | partly_explained | unexplained | nothing_missing
  std::vector<Alternative> paths;              // when the search followed several first choices
  std::vector<std::string> revisions;          // choices the forward-backward revisit changed, in words
  std::string rescue;                          // round 1 added nothing: the pairs tried jointly, in words (empty: none)
  std::vector<ParamCorrelation> correlations;  // |rho| >= kReportCorrelation, between added effects
  std::vector<NotIdentifiable> not_identifiable;
  std::vector<Rival> rivals;         // explanations this file does not tell from the one found
  std::vector<std::string> summary;  // plain-language verdict
  ResidualReport before, after;
  std::shared_ptr<const plant::Plant> fitted;  // the input model (noise included) with the found effects
  double wall_s = 0;
  int evaluations = 0;
};

struct DiagnoseSettings {
  std::vector<std::string> candidates;  // empty: all (built in + user effects)
  unsigned threads = 0;                 // 0: min(2, hardware)
  int max_rounds = 4;
  std::size_t coarse_rows = 50000;  // coarse fits run on a decimated copy about this long
  bool keep_series = true;          // plots for the report
  bool progress = false;            // one line per round on stderr
  // Set from another thread to stop: diagnose throws Cancelled before its next fit (cancel.hpp).
  const std::atomic<bool>* cancel = nullptr;
};

Diagnosis diagnose(const plant::Plant& model, const Measurement& data, const DiagnoseSettings& settings = {});
// Several files of one rig at once: one set of parameters fitted to all of them, so that what one
// run cannot separate, several runs with other motion can. All with the encoder column or all
// without (std::invalid_argument otherwise).
Diagnosis diagnose(const plant::Plant& model, const std::vector<const Measurement*>& files,
                   const DiagnoseSettings& settings = {});

using DataFiles = std::vector<std::filesystem::path>;
std::string diagnosis_json(const Diagnosis& d, const std::filesystem::path& model_file, const DataFiles& data_files);
// The diagnosis as a report page (report.html).
std::string diagnosis_report_html(const Diagnosis& d, const std::filesystem::path& model_file, const DataFiles& data_files);
// The fitted model as YAML, with a header naming what was added.
std::string fitted_model_yaml(const Diagnosis& d, const std::filesystem::path& model_file, const DataFiles& data_files);

struct DiagnoseOptions {
  std::filesystem::path model_file, out_dir, write_model;  // write_model empty: none
  DataFiles data_files;                                    // one or more (see diagnose above)
  // The files' CSV dialect (--separator, --decimal, --columns); a file of several acquisitions
  // appended (time restarting) is read as one file each (load_acquisitions).
  CsvDialect dialect;
  DiagnoseSettings settings;
  bool quiet = false;
};
// The whole command: prints the verdict, writes DIR/diagnosis.json, DIR/report.html and the model.
Diagnosis run_diagnose(const DiagnoseOptions& options);

}  // namespace hil::analysis
