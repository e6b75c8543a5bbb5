// diagnose's search, internal (analysis/README.md, Method): what one candidate's fit is
// (diagnose_fit.cpp: LM and grid search of a variant, joint refits, a step time's profile), and
// how effects are chosen (diagnose_search.cpp: rounds, paths, the revisit, the forms). The
// criterion that judges them is criterion.hpp; the verdict in words diagnose_words.cpp;
// diagnose.cpp runs the whole.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "criterion.hpp"
#include "hil/analysis/candidates.hpp"
#include "hil/analysis/diagnose.hpp"
#include "hil/analysis/replay.hpp"
#include "hil/parallel_for.hpp"

namespace hil::analysis::detail {

using Clock = std::chrono::steady_clock;
inline constexpr double kInf = std::numeric_limits<double>::infinity();
inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Search settings (the selection thresholds are criterion.hpp's).
inline constexpr std::size_t kRefineTop = 2;  // candidates refined on every row per round
inline constexpr int kCoarseIter = 12, kGridIter = 2, kRefineIter = 3, kJointIter = 8;
inline constexpr double kCompetitive = 1.2;  // variants within 20 % of their best get a full-data look
// A joint refit's start whose coarse-copy end fits more than 2 % worse than the best start's is not
// refitted on every row (joint_refit).
inline constexpr double kJointTie = 0.02;
inline constexpr std::size_t kGridCoarse = 16;   // grid values of the zoom search's first level
inline constexpr std::size_t kGridZoom = 8;      // values per later level
inline constexpr std::size_t kInPlaceTried = 2;  // effects refitted in an accepted effect's place (revisit)
inline constexpr std::size_t kBeam = 3;          // first choices followed when the best one is not enough
inline constexpr int kRevisitPasses = 3;         // passes of one revisit that may change the model
inline constexpr int kFormRevisions = 2;         // times revise_variants may send the model back to the revisit
inline constexpr int kForwardAgain = 2;          // forward rounds after a revision changed the model (diagnose)
inline constexpr int kVariantPasses = 3;         // passes of revise_variants
inline constexpr std::size_t kRescueTop = 3;     // candidates short only of the excess share fitted in pairs (rescue_pair)

// Candidates, variants and grid values run on the threads through the one parallel loop
// (hil/parallel_for.hpp): each index once, the first error (cancellation) rethrown.
using hil::parallel_for;

double rss_of(const plant::Plant& model, const ReplayData& data, std::vector<double>* residual);

// One variant's fit: continuous parameters by LM, at most one grid parameter by search.
struct VariantFit {
  std::size_t candidate = 0, variant = 0;
  std::vector<FreeParam> continuous;
  const FreeParam* grid = nullptr;
  double grid_value = kNaN;
  std::vector<double> values, sigma;  // continuous
  double rss_coarse = kInf;           // on the decimated copy
  double rss_full = kInf;             // on every row
  double wrss_full = kInf;            // on every row, whitened by the noise model (criterion.hpp)
  bool refined = false;
  // The accepted effects' continuous values from the joint refine with this candidate (in the
  // order of apply_added); empty: they were held at their values.
  std::vector<double> added_values;
  int evaluations = 0;
  std::string note;
  std::size_t k() const { return continuous.size() + (grid ? 1 : 0); }
};

struct Context {
  const ReplayData& full;
  const ReplayData& coarse;
  unsigned threads;
  const std::atomic<bool>* cancel;  // looked at before every fit (cancel.hpp)
  const detail::Criterion& criterion;
};

// A model on every row: its residual's sum of squares, plain and whitened by the noise model.
struct Score {
  double rss = kInf, wrss = kInf;
};
Score score_of(const Context& ctx, const plant::Plant& model);

plant::Plant model_for(const plant::Plant& attached, const VariantFit& v, double grid_value);
// vf's variant's parameters: the grid one (at most one) and the continuous ones.
void split_params(const Candidate& cand, VariantFit& vf);
// Fits vf's variant on the coarse copy: starts, LM, the grid parameter's zoom search.
void fit_variant(const Context& ctx, const plant::Plant& base, const Candidate& cand, VariantFit& vf);
// RSS on every row at the coarse fit's values.
void evaluate_full(const Context& ctx, const plant::Plant& base, const Candidate& cand, VariantFit& vf);
// LM on every row from the coarse fit's values.
void refine_variant(const Context& ctx, const plant::Plant& base, const Candidate& cand, VariantFit& vf);
// The ranking's entry of a fitted variant.
CandidateResult describe(const Candidate& cand, const VariantFit& vf, const plant::Plant& base);

// An added effect, kept so that the fitted model can be rebuilt on the noise-including model.
struct Added {
  const Candidate* cand;  // points into `all_candidates` (stable for the run)
  VariantFit fit;
};

plant::Plant apply_added(const plant::Plant& model, const std::vector<Added>& added);

// Jointly refits every added effect's continuous parameters (the first fit of an effect absorbed
// part of the ones found after it).
void joint_refit(const Context& ctx, const plant::Plant& base0, std::vector<Added>& added, int& evaluations);

// Refits a candidate on every row together with the accepted effects (none held fixed): an
// effect accepted earlier may have absorbed part of this one, and a fit of the newcomer against
// it frozen would understate what the two explain together (valve offset against an erosion that
// took part of it). The candidate's RSS for the criterion is the joint one.
void refine_jointly(const Context& ctx, const plant::Plant& base0, const std::vector<Added>& added, const Candidate& cand,
                    VariantFit& vf);

// Takes over the accepted effects' values that the chosen candidate's joint refine found.
void adopt_joint_values(std::vector<Added>& added, const VariantFit& chosen);

// How far an added effect's grid parameter (a step time) can move and still fit: its profile.
// A step is located only by the motions around it; between two motions every time fits as well,
// and the best grid value alone would claim more than the data say. From the chosen value the
// walk steps outwards, doubling its stride while the cost stays within one standard error of the
// best (the RSS of the coarse copy may rise by s^2 tau: the residual's variance times its
// correlation time, a one-parameter chi-square of 1 for correlated noise), then bisects to the
// last grid value inside. At each value the effect's continuous parameters are refitted (a short
// LM from their values), the other effects held. Both directions run at once. NaN when the
// effect has no grid parameter.
std::pair<double, double> grid_span(const Context& ctx, const plant::Plant& base0, const std::vector<Added>& added,
                                    std::size_t which, int& evaluations);

// --- one round, a path of rounds -----------------------------------------------------------------

struct Setup {
  Context ctx;
  double noise_rss = 0;  // N sigma^2
  double spread = 0;     // |y - mean(y)| / sqrt(N)
  bool progress = false;
  Clock::time_point t_start;
};

struct RoundOutcome {
  Round round;
  std::vector<Added> earning;  // candidates that earn their place, best first
  // Candidates that fail only the excess-share rule (dBIC below the margin, 5 % of the noise
  // power), lowest dBIC first: what rescue_pair may fit in pairs.
  std::vector<Added> short_of_share;
};

// Ranks the candidates of `pool` against base0 with `added`: fits, criterion, the ones that earn their place.
RoundOutcome run_round(const Setup& su, const plant::Plant& base0, const std::vector<Added>& added,
                       const std::vector<const Candidate*>& pool, int& evaluations);

// A sequence of added effects and the rounds that chose them.
struct Path {
  std::vector<Added> added;
  std::vector<Round> rounds;
  double rss = kInf;   // of the path's final model, every row
  double wrss = kInf;  // the same whitened by the noise model (criterion.hpp)
};

// The candidates of `pool` not in `added`.
std::vector<const Candidate*> remaining(const std::vector<const Candidate*>& pool, const std::vector<Added>& added);

// Adds the chosen effect, refits jointly, and continues greedily until nothing earns its place.
void continue_path(const Setup& su, const plant::Plant& base0, const std::vector<const Candidate*>& pool, Path& path,
                   int max_rounds, int& evaluations);

// Round 1 added nothing although the model is above the noise floor: two effects can mask each
// other (a higher burn rate and an eroded throat nearly cancel, so neither alone removes a quarter
// of the excess), and every candidate then fails only the excess-share rule. Of
// `first.short_of_share` (lowest dBIC first), every pair among the kRescueTop first and the first
// with each of the rest is fitted jointly, every form of each (joint_refit, both free, from their
// single fits and from fresh starts); a pair's forms with the lowest whole-model BIC stand for it. A pair is accepted when together they
// remove kPairExcessShare of the excess (what two effects added one by one would have to) and
// each earns its place beside the other by why_not_earning against the other alone (its single
// fit on every row): dBIC, a quarter of the excess that the other leaves, 5 % of the noise power.
// Of the accepted pairs the lowest whole-model BIC is kept: `path` gets round 1 (adding the
// member with the lower dBIC alone) and a round for the second member against the first, and the
// caller continues it as any path. `told` says which pairs were tried and why each was or was not
// taken (round 1's note). False, `path` untouched, when no pair is accepted or none was tried.
bool rescue_pair(const Setup& su, const plant::Plant& base0, const RoundOutcome& first, Path& path, std::string& told,
                 int& evaluations);

// BIC of a whole model (criterion.hpp): N ln W + k ln N, k all added effects' free parameters.
double path_bic(const Setup& su, const std::vector<Added>& added, double wrss);

// The path's RSS on every row, plain and whitened (into path.rss, path.wrss).
void measure_path(const Setup& su, const plant::Plant& base0, Path& path, int& evaluations);

// Revisits the choices of a path (forward-backward): for each accepted effect, the others are
// refitted without it; if it no longer earns its place against them (dBIC >= -10; the 5 % share of
// the noise power is a bar to enter only) it is dropped; otherwise a round over the candidates not in the model
// asks for the best other effect in its place (a valve offset that a burn rate exponent plus a
// sensor offset had stood in for). If that gives a lower whole-model BIC it is swapped in. Passes
// repeat until one changes nothing (at most kRevisitPasses passes change anything; each change is
// told in `revisions`). In that last pass, an alternative whose BIC is within kRivalBic of the
// found model's is a rival: the file does not tell the two apart by the criterion's own margin.
// Those are returned. A one-effect model has nothing to drop but is asked for rivals too.
std::vector<Rival> revisit(const Setup& su, const plant::Plant& base0, const std::vector<const Candidate*>& pool, Path& path,
                           std::vector<std::string>& revisions, int& evaluations);

// A variant chosen in an early round can keep a parameter that a later effect made idle (a gap
// step of 0.001 deg once a sensor lag took over what the step had mimicked: with several files a
// per-file step can stand for a speed-dependent lag), or be the wrong form of the right effect
// with another effect making up the difference (proportional erosion where it was additive, and a
// sensor gain of 0.91 with an offset of 139 kPa covering what the wrong form left:
// triple_erosion_bias_delay stopped at 94.4 % for a floor of 98.8 %). For each accepted effect,
// every other variant of its candidate with no more parameters than the chosen one (a simpler
// form, or a sibling form of as many) is tried in its place, all accepted effects refitted with
// it; it replaces the chosen variant when the whole model's BIC is lower. A change can make
// another effect's simpler form the better one (the gain goes idle once the erosion is right), so
// the effects are gone over again until nothing changes (at most kVariantPasses times). Told in
// `revisions`; true when anything changed.
bool revise_variants(const Setup& su, const plant::Plant& base0, Path& path, std::vector<std::string>& revisions,
                     int& evaluations);

// A form marked `extension` (Variant) is tried only here: in place of an accepted form of its
// effect whose parameters it holds (a gap step that absorbed a drift, then a drift and a step),
// from the accepted form's values and from a fresh fit against the other effects, all refitted.
// It replaces the accepted form only when its extra parameters earn their place against it by the
// criterion (why_not_earning: dBIC, a quarter of the excess, 5 % of the noise power), as a new
// effect must; so a file the simpler forms do not pick the effect for never sees it. Told in
// `revisions`; true when anything changed.
bool extend_forms(const Setup& su, const plant::Plant& base0, Path& path, std::vector<std::string>& revisions, int& evaluations);

// The verdict and the summary in words (diagnose_words.cpp), from a filled Diagnosis.
void write_verdict(Diagnosis& d, std::size_t n_files);
// A fitted parameter as text: value, uncertainty, its limits and plausibility.
std::string param_text(const FittedParam& p);
// Several files: an event time found on the runs' joint clock (replay.hpp) becomes "file k, t s
// after its first row"; a step between two runs is at 0 s of the later file.
void localise_event_times(std::vector<FittedParam>& params, const ReplayData& data);

}  // namespace hil::analysis::detail
