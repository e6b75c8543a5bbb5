// diagnose's selection criterion, in one place (internal; analysis/README.md, Criterion).
//
// The residual e = measured - model is judged as the Gaussian likelihood of the measurement noise
// as a process (noise_model.hpp): e is passed through the noise's whitening filter, which turns a
// perfect model's residual into white noise of unit variance, and
//   BIC = N ln(sum w^2) + k ln N,   dBIC = N ln(W_candidate / W_model) + k ln N,
// N the rows, W the whitened residual's sum of squares, k the free parameters. Every row counts:
// the noise's own correlation is taken out by the filter, not by shrinking N, so a slow misfit
// that remains (another effect still missing) does not shrink the evidence the way an effective
// sample size N / tau_int of the residual did (N_eff fell to 11-24 of 30 000 rows on a file with
// a drifting gap still missing, and an effect whose removal cost 1.8 times the noise power could
// not earn its place). Fitting only noise lowers W by about one per parameter, against ln N.
// Several files: each segment is whitened by its own file's noise model.
//
// Which of several candidates that earn their place is added first is a different question: the
// order of choice. There the residual still holds the large misfit of everything missing, and
// counted on every row any small difference in fit between two stand-ins (a sensor offset and gain
// for a valve offset) outweighs a parameter more (ln N ~ 10 whitened units against thousands); the
// greedy search then took the wrong one first and ended at the floor with two effects for one
// (pair_offset_delay: sensor bias + burn-rate refit + delay for offset + delay). So the order is by
// the same BIC counted on the whitened residual's effective rows, N / tau of the best candidate's
// whitened residual (choice_delta_bic): while structure remains it weighs a parameter as much as
// the structure's own independent pieces, and at the floor (tau ~ 1) it is the criterion itself.
#pragma once

#include <cmath>
#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include "hil/analysis/noise_model.hpp"
#include "hil/analysis/replay.hpp"
#include "hil/analysis/residuals.hpp"
#include "text.hpp"

namespace hil::analysis::detail {

// Selection thresholds (analysis/README.md, Criterion and Selection).
inline constexpr double kBicMargin = -10;        // very strong evidence (Kass & Raftery)
inline constexpr double kMinExcessShare = 0.25;  // of the model's excess error power
inline constexpr double kMinNoiseShare = 0.05;   // of N sigma^2
inline constexpr double kFloorTolerance = 1.1;   // RSS within 10 % of N sigma^2: at the noise floor
inline constexpr double kSkipAtFloor = 1.03;     // RSS within 3 %: no candidate can earn its place
// Two effects added at once (rescue_pair, diagnose_search.hpp) remove together what two added one
// by one would have had to: a quarter of the excess each.
inline constexpr double kPairExcessShare = 2 * kMinExcessShare;

// Why a candidate does not earn its place against the current model (empty: it does): dBIC below
// kBicMargin, and a real improvement: `gain` (RSS removed) at least a quarter of the excess
// (RSS - N sigma^2; the bar that keeps named candidates from nibbling at an out-of-list misfit)
// and 5 % of the noise power N sigma^2 (not noise fitting).
inline std::string why_not_earning(double delta_bic, double gain_pa2, double excess_pa2, double noise_rss_pa2) {
  if (!(delta_bic < kBicMargin))
    return "information criterion: dBIC " + text::num(delta_bic, 3) + " is not below " + text::num(kBicMargin, 2);
  if (gain_pa2 < kMinExcessShare * excess_pa2)
    return "explains only " + text::num(100 * (excess_pa2 > 0 ? gain_pa2 / excess_pa2 : 0), 2) +
           " % of the excess error (needs 25 %)";
  if (gain_pa2 < kMinNoiseShare * noise_rss_pa2)
    return "improvement below 5 % of the noise power (the model is at the noise floor)";
  return {};
}

class Criterion {
 public:
  // One noise model per segment of `data` (file).
  Criterion(const ReplayData& data, std::vector<NoiseModel> noise) : data_(data), noise_(std::move(noise)) {}

  double rows() const { return static_cast<double>(data_.scored_rows()); }  // left-out rows are no evidence
  // Sum of squares of the residual (every row of `data`) whitened by each file's noise model.
  double whitened_rss(std::span<const double> residual_pa) const {
    double sum = 0;
    for (std::size_t i = 0; i < data_.segments.size(); ++i) {
      const std::size_t b = data_.segment_begin(i), e = data_.segment_end(i);
      sum += noise_[i].whitened_rss(residual_pa.subspan(b, e - b));
    }
    return sum;
  }
  // A model's BIC up to a constant: N ln W + k ln N.
  double bic(double whitened_rss, std::size_t k) const {
    return rows() * std::log(whitened_rss) + static_cast<double>(k) * std::log(rows());
  }
  // Adding k parameters that take W from `before` to `after`.
  double delta_bic(double whitened_rss_after, double whitened_rss_before, std::size_t k) const {
    return rows() * std::log(whitened_rss_after / whitened_rss_before) + static_cast<double>(k) * std::log(rows());
  }
  // The whitened residual's effective rows, N / tau_int (the order of choice, above).
  double effective_rows(std::span<const double> residual_pa) const {
    std::vector<double> w(residual_pa.size());
    for (std::size_t i = 0; i < data_.segments.size(); ++i) {
      const std::size_t b = data_.segment_begin(i), e = data_.segment_end(i);
      noise_[i].whiten(residual_pa.subspan(b, e - b), std::span<double>(w).subspan(b, e - b));
    }
    return rows() / integrated_autocorrelation_time(w);
  }
  // The order of choice between candidates: the same BIC on `n_eff` effective rows.
  static double choice_delta_bic(double whitened_rss_after, double whitened_rss_before, std::size_t k, double n_eff) {
    return n_eff * std::log(whitened_rss_after / whitened_rss_before) + static_cast<double>(k) * std::log(n_eff);
  }
  const NoiseModel& noise(std::size_t file) const { return noise_[file]; }

 private:
  const ReplayData& data_;
  std::vector<NoiseModel> noise_;
};

}  // namespace hil::analysis::detail
