// What a measurement file itself shows that no model explains and a replay cannot undo: a hole in
// the log, a pressure that repeats in runs (a reading updated slower than it is logged), rows
// piled at the file's highest or lowest reading (a saturated transducer or logger range), a
// pressure beyond the model's reach (another unit), a start the model cannot make. Without these
// a fit takes them for physics: a 100 Hz reading logged at 1 kHz was "explained" by a 5 ms sensor
// lag and called mains hum; a 3 s dropout became "something changed at 9.75 s". Each becomes a
// plain-language warning that compare and diagnose put first. Offline code: allocates.
#pragma once

#include <cstddef>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace hil::analysis {

class LogChecks {
 public:
  // The model's reach in pressure (NaN: unknown).
  LogChecks(double model_lo_pa, double model_hi_pa) : model_lo_pa_(model_lo_pa), model_hi_pa_(model_hi_pa) {}
  void add(double t_s, double p_pa);  // each row, in file order
  // A row left out (a run's fault window, run_inputs.hpp): no hole, and no repeat across it.
  void skip(double t_s) {
    if (rows_ > 0) t_prev_s_ = t_s, p_prev_pa_ = std::numeric_limits<double>::quiet_NaN();
  }
  // The replay's start: the measured pressure of the first rows, what the model makes there at the
  // measured angle (Plant::settle_nearest), and that angle.
  void start(double p0_pa, double yhat0_pa, double angle0_rad);
  // noise_sigma_pa: the residual's noise estimate (clipping is only told on a noisy reading: a
  // noise-free simulation's dwell at its highest level repeats that level exactly too).
  std::vector<std::string> warnings(double noise_sigma_pa) const;

  // Thresholds, each a statement about a log of this rig.
  static constexpr double kHoleMinS = 0.05;          // a hole: above this and kHoleSamples samples
  static constexpr double kHoleSamples = 10;         // of the file's typical interval
  static constexpr double kStaleRepeatShare = 0.5;   // rows equal to the row before
  static constexpr double kStaleRegularShare = 0.6;  // runs within one row of the median run
  static constexpr double kPiledShare = 0.01;        // rows at exactly the extreme reading
  static constexpr std::size_t kPiledMinRows = 20;
  static constexpr double kClipMinNoisePa = 100;     // a reading this noisy never repeats its extreme
  static constexpr double kStartMisfitShare = 0.05;  // of the first rows' pressure

 private:
  double model_lo_pa_, model_hi_pa_;
  std::size_t rows_ = 0;
  double t_prev_s_ = 0, p_prev_pa_ = 0, sum_p_pa_ = 0;
  std::vector<double> first_dt_s_;                    // the first intervals: the typical one
  std::vector<std::pair<double, double>> long_gaps_;  // (t before, length) of intervals over kHoleMinS
  std::size_t repeats_ = 0, run_ = 1;
  std::vector<std::size_t> run_lengths_;  // count of finished runs by length (last bin: longer)
  double p_max_pa_ = 0, p_min_pa_ = 0;
  std::size_t at_max_ = 0, at_min_ = 0;
  double p0_pa_ = 0, yhat0_pa_ = 0, angle0_rad_ = 0;
  bool started_ = false;
  double typical_dt_s() const;
};

}  // namespace hil::analysis
