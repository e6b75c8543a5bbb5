// Bounded Levenberg-Marquardt on replay residuals, with numerical Jacobians (internal).
// The residual of a parameter vector is measured - predicted over every row of a ReplayData;
// parameters live in [lo, hi] (steps are projected onto the box) and are scaled by FreeParam::scale.
#pragma once

#include <atomic>
#include <cstddef>
#include <vector>

#include "hil/analysis/candidates.hpp"
#include "hil/analysis/replay.hpp"
#include "hil/parallel_for.hpp"

namespace hil::analysis::detail {

struct FitResult {
  std::vector<double> values;  // in the order of the problem's params
  std::vector<double> sigma;   // 1-sigma uncertainty (NaN: not computed / not identifiable)
  double rss = 0;              // on the data it was fitted on
  bool ok = false;             // the model could be replayed at `values`
  int evaluations = 0;         // replays run
};

class Fitter {
 public:
  // `model`: the base with the effect attached (neutral values); params: the free parameters.
  // threads: replays of one Jacobian's columns and of the starting points run on up to this many
  // threads (a fit run alone, as the joint refits are, would leave the other core idle); 1 when
  // the fit itself is one of several run in parallel. The result does not depend on it.
  Fitter(const plant::Plant& model, std::vector<FreeParam> params, const ReplayData& data, unsigned threads = 1);

  // RSS at `values` (+inf if the model cannot be replayed there). Also fills `residual` if given.
  double cost(const std::vector<double>& values, std::vector<double>* residual = nullptr);
  // The best of the starting points (cartesian product of each param's starts, capped).
  std::vector<double> best_start(double* rss);
  // Levenberg-Marquardt from `x0`, at most max_iter Jacobians.
  FitResult levenberg_marquardt(std::vector<double> x0, int max_iter);
  // 1-sigma uncertainties at `x`: s^2 (J^T J)^-1 with s^2 = RSS / (N - p), inflated by the
  // residual's integrated autocorrelation time (correlated residuals carry less information).
  // correlation (optional): the parameters' correlation matrix, (J^T J)^-1 normalised; left
  // empty when it cannot be computed.
  std::vector<double> uncertainty(const std::vector<double>& x, std::vector<std::vector<double>>* correlation = nullptr);
  int evaluations() const { return evaluations_.load(); }
  const std::vector<FreeParam>& params() const { return params_; }

 private:
  std::vector<double> clamp(std::vector<double> x) const;
  // cost() with the prediction written into `yhat` (size data_.size()): one buffer per thread.
  double cost_into(const std::vector<double>& values, std::vector<double>& yhat, std::vector<double>* residual);
  // body(yhat, i) for i in [0, n), on threads_ threads, each with its own prediction buffer.
  template <class Body>
  void run_each(std::size_t n, Body&& body) {
    if (threads_ <= 1 || n <= 1) {
      for (std::size_t i = 0; i < n; ++i) body(yhat_, i);
      return;
    }
    hil::parallel_for(
        n, threads_, [&] { return std::vector<double>(data_.size()); },
        [&](std::vector<double>& yhat, std::size_t i) { body(yhat, i); });
  }
  bool jacobian(const std::vector<double>& x, const std::vector<double>& r0, std::vector<std::vector<double>>& cols);

  const plant::Plant& model_;
  std::vector<FreeParam> params_;
  const ReplayData& data_;
  double sample_period_s_ = 0;  // mean row spacing of the data's first segment (0: one row)
  unsigned threads_ = 1;
  std::vector<double> yhat_;
  std::atomic<int> evaluations_{0};
};

// Solves the small symmetric system A x = b (Gaussian elimination with pivoting); false if singular.
bool solve(std::vector<std::vector<double>> a, std::vector<double> b, std::vector<double>& x);
// Inverse of a small symmetric positive matrix; false if singular.
bool invert(const std::vector<std::vector<double>>& a, std::vector<std::vector<double>>& inv);

}  // namespace hil::analysis::detail
