// The residual against the drive velocity around zero (issue 37 point 4): a valve that sticks
// (stick-slip, static friction) or a play the model does not have leaves its misfit where the
// drive is slow or still, and little while it moves fast. No candidate holds a stick-slip, so when
// nothing explains the residual the signature says where in velocity it lives. Internal to
// residuals*.cpp.
//
// How: the residual's sums in bins of asinh(v / 1 deg/s) (fine near zero, coarse at speed). For
// each band |v| < X (X from kBandsDegS) the mean square inside and outside; the narrowest band
// that holds at least kBandExcessShare of the excess error power (the mean square above the
// noise's) in at most kBandMaxRows of the rows, with a mean square inside kBandContrast times the
// one outside and an RMS inside of at least twice the noise, is named. Otherwise, a misfit that
// flips with the direction of motion (a friction or a play: under closed loop a stuck valve's error
// persists while the drive moves, so it is not confined to slow rows, but its sign follows the
// direction): the narrowest band |v| < X whose mean residual while opening (0 < v < X) and while
// closing (-X < v < 0) differ by kFlipSigmas noise RMS, each side on at least kFlipMinRows of the
// rows, and whose split by direction holds at least kFlipExcessShare of the excess power.
// diagnose reads the band of the residual before the effects it found, in what remains after them
// (rms_below: diagnose_words.cpp, the verdict).
// Offline code: allocates.
#pragma once

#include <array>
#include <cstddef>
#include <vector>

#include "hil/analysis/residuals.hpp"

namespace hil::analysis::detail {

struct VelocityBand {
  double below_deg_s = 0;                           // 0: no band named
  double rms_in_pa = 0;                             // residual RMS at |v| < below_deg_s
  double rms_out_pa = 0;                            // and elsewhere
  double rows_share = 0;                            // of all rows inside the band
  double excess_share = 0;                          // of the excess error power inside the band
  bool flips = false;                               // named for a sign that follows the direction (not a concentration)
  double mean_opening_pa = 0, mean_closing_pa = 0;  // at 0 < v < X and -X < v < 0 (flips)
};

class VelocityProfile {
 public:
  void add(double velocity_deg_s, double e_pa);
  // The residual's mean and RMS against the drive velocity (asinh bins).
  Binned binned() const;
  // The narrowest velocity band around zero that holds the misfit (none when it is spread).
  VelocityBand band(double noise_sigma_pa) const;

  static constexpr std::array<double, 8> kBandsDegS = {0.5, 1, 2, 3, 5, 10, 20, 50};
  static constexpr double kBandExcessShare = 0.5;
  static constexpr double kBandMaxRows = 0.5;
  static constexpr double kBandContrast = 4;
  static constexpr double kFlipSigmas = 4, kFlipMinRows = 0.005, kFlipExcessShare = 0.25;

 private:
  static constexpr double kScaleDegS = 1;    // asinh scale: bins fine below 1 deg/s
  static constexpr double kBinWidth = 0.25;  // in asinh units
  static constexpr int kBins = 64;           // +-8 asinh units: up to ~1500 deg/s
  std::vector<double> sum_ = std::vector<double>(kBins), sum2_ = std::vector<double>(kBins);
  std::vector<std::size_t> count_ = std::vector<std::size_t>(kBins);
  // Exact band sums (bins would blur the band's edge): per kBandsDegS entry, inside.
  std::array<double, kBandsDegS.size()> in_sum2_{};
  std::array<std::size_t, kBandsDegS.size()> in_count_{};
  std::array<double, kBandsDegS.size()> pos_sum_{}, neg_sum_{};
  std::array<std::size_t, kBandsDegS.size()> pos_count_{}, neg_count_{};
  double all_sum2_ = 0;
  std::size_t all_count_ = 0;
};

// The residual inside and outside |v| < below_deg_s from a profile's bins (binned() above): the
// bins whose centre lies inside, so the band's edge is read to within half a bin (an eighth of an
// asinh unit: 5 deg/s is read as 4.7). RMS NaN on a side no bin lies on.
struct BandSplit {
  double rms_in_pa = 0, rms_out_pa = 0, rows_share = 0;
};
BandSplit split_at(const Binned& profile, double below_deg_s);

}  // namespace hil::analysis::detail
