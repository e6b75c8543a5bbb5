// The residual against the drive angle (encoder when logged, else the command), and a ripple
// periodic in that angle (issue 37 point 4): an effect none of the candidates holds, such as a
// gear's transmission error (one period per tooth) or a coupling's eccentricity (one per turn),
// shows as a residual that repeats with the angle, not with time. Internal to residuals.cpp.
//
// How: the residual's mean in fine angle bins (kBinDeg); for each trial period P (log grid from 4
// bins to a third of the angle span covered), the bin means minus their moving average over one
// period (which removes whatever varies slower than P, and keeps a ripple of period P whole) are
// fitted by a cosine and a sine of period P, each bin weighted by its samples. The period with the
// largest explained power is reported when that power is far above what the noise alone would
// explain (kEvidence times the chi-square's expectation) and its amplitude is at least half the
// noise RMS; otherwise none.
// Offline code: allocates.
#pragma once

#include <cstddef>
#include <vector>

#include "hil/analysis/residuals.hpp"

namespace hil::analysis::detail {

struct AngleRipple {
  double period_deg = 0;    // 0: no ripple found
  double amplitude_pa = 0;  // of the fitted sinusoid
  double span_deg = 0;      // angle span the bins cover
  double power_share = 0;   // of the detrended bin means' weighted power
};

class AngleProfile {
 public:
  void add(double drive_deg, double e_pa);
  // The residual's mean and RMS against the angle, in about 60 bins over the span covered.
  Binned binned() const;
  // The strongest ripple periodic in the angle; noise_sigma_pa is the measurement noise's RMS.
  AngleRipple ripple(double noise_sigma_pa) const;

 private:
  static constexpr double kBinDeg = 0.02;
  static constexpr double kMaxAbsDeg = 360;  // the measurement's own limit on angles
  std::vector<double> sum_, sum2_;
  std::vector<std::size_t> count_;
};

}  // namespace hil::analysis::detail
