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
#pragma once

#include <cmath>
#include <cstddef>
#include <span>
#include <vector>

#include "hil/analysis/noise_model.hpp"
#include "hil/analysis/replay.hpp"

namespace hil::analysis::detail {

class Criterion {
 public:
  // One noise model per segment of `data` (file).
  Criterion(const ReplayData& data, std::vector<NoiseModel> noise) : data_(data), noise_(std::move(noise)) {}

  double rows() const { return static_cast<double>(data_.size()); }
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
  const NoiseModel& noise(std::size_t file) const { return noise_[file]; }

 private:
  const ReplayData& data_;
  std::vector<NoiseModel> noise_;
};

}  // namespace hil::analysis::detail
