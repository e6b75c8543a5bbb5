// The measurement noise as a process, estimated from the measured pressure alone: what a perfect
// model leaves, and how it is correlated in time. One place for it: compare's noise floor and
// signature, diagnose's verdict and its selection criterion all read it from here.
//
// The form: first-order coloured noise plus white noise,
//   n(k) = x(k) + w(k),  x(k) = phi x(k-1) + u(k),  var x = coloured^2,  var w = white^2.
// A transducer's first-order anti-alias filter at f_c, sampled every dt, gives exactly the AR(1)
// part (phi = exp(-2 pi f_c dt)); the ADC's own noise and the quantisation error are the white
// part. (A second-order filter is approximated by the nearest first-order one.)
//
// How: third differences of the reading at a spacing of a rows, y(k) - 3 y(k-a) + 3 y(k-2a) -
// y(k-3a), cancel the chamber's slow pressure (its 0.1 s dynamics leave under a kPa even at a =
// 8 ms), so what they carry is the noise through a known filter. Their robust variance V(a) (1.4826
// * median, read as grouped data for a quantised reading, as before) grows with a while the
// colour is still correlated over a rows: V(a) = 20 white^2 + coloured^2 (20 - 30 phi^a + 12
// phi^2a - 2 phi^3a). White noise gives the same V at every a. phi is fitted on a grid and the two
// levels by least squares; the colour is kept only when it fits the V(a) clearly better than white
// noise alone (noise_model.cpp: kColourEvidence). The total sigma^2 = white^2 + coloured^2 is the
// noise floor. Spacings reach 8 ms of time (longer, the chamber's own curvature enters), so a
// colour slower than about phi = 0.9 per row is seen only in part.
// Offline code: allocates.
#pragma once

#include <cstddef>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace hil::analysis {

inline constexpr double kNoiseMaxPhi = 0.95;  // beyond this the second difference cannot see the colour

struct NoiseModel {
  double sigma_pa = 0;           // total RMS: the error a perfect model leaves (the noise floor)
  double white_sigma_pa = 0;     // of the white part (ADC noise, quantisation)
  double coloured_sigma_pa = 0;  // of the first-order coloured part
  double phi = 0;                // its pole per sample (0: white noise)
  double sample_period_s = 0;    // median row spacing, for phi's corner frequency (0: unknown)
  std::string method;            // how sigma was obtained, in words
  // The innovations form (1 - phi q^-1) n = (1 - theta q^-1) eps, eps white with RMS
  // innovation_sigma_pa: the one-step prediction error of the noise. Filled by NoiseEstimator::finish.
  double theta = 0;
  double innovation_sigma_pa = 0;
  bool coloured() const { return coloured_sigma_pa > 0 && phi > 0; }
  // The coloured part's corner frequency -ln(phi) / (2 pi dt), Hz (0: white or dt unknown).
  double corner_hz() const;
  // Integrated autocorrelation time of the noise, samples: 1 + 2 sum rho(l).
  double correlation_time_samples() const;
  // Residual e (rows of one file, in order) through the noise's whitening filter, divided by the
  // innovation RMS: a perfect model's residual becomes white noise of unit variance. The first row
  // has no past and is left out (out[0] = 0).
  void whiten(std::span<const double> e_pa, std::span<double> out) const;
  // Sum of squares of whiten(e): the residual's misfit counted in units of the noise's own
  // one-step prediction error (diagnose's criterion).
  double whitened_rss(std::span<const double> e_pa) const;
};

// Streams the measured pressure row by row; finish() fits the noise model.
class NoiseEstimator {
 public:
  NoiseEstimator();
  ~NoiseEstimator();
  NoiseEstimator(NoiseEstimator&&) noexcept;
  NoiseEstimator& operator=(NoiseEstimator&&) noexcept;
  void add(double t_s, double y_pa);  // rows in time order (the first rows give the sample period)
  NoiseModel finish();                // once, at the end of the stream

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

NoiseModel noise_model_from_data(std::span<const double> y_pa, double sample_period_s = 0);
// The total RMS of noise_model_from_data (the noise floor).
double noise_sigma_from_data(const std::vector<double>& y_pa);

}  // namespace hil::analysis
