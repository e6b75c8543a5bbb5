#include "velocity_signature.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace hil::analysis::detail {

void VelocityProfile::add(double velocity_deg_s, double e_pa) {
  if (!std::isfinite(velocity_deg_s) || !std::isfinite(e_pa)) return;
  const double u = std::asinh(velocity_deg_s / kScaleDegS) / kBinWidth + kBins / 2.0;
  const auto b = static_cast<std::size_t>(std::clamp(u, 0.0, kBins - 1.0));
  sum_[b] += e_pa;
  sum2_[b] += e_pa * e_pa;
  ++count_[b];
  for (std::size_t i = 0; i < kBandsDegS.size(); ++i) {
    if (std::abs(velocity_deg_s) >= kBandsDegS[i]) continue;
    in_sum2_[i] += e_pa * e_pa, ++in_count_[i];
    if (velocity_deg_s > 0) pos_sum_[i] += e_pa, ++pos_count_[i];
    if (velocity_deg_s < 0) neg_sum_[i] += e_pa, ++neg_count_[i];
  }
  all_sum2_ += e_pa * e_pa;
  ++all_count_;
}

Binned VelocityProfile::binned() const {
  Binned out;
  out.quantity = "drive velocity";
  out.unit = "deg/s";
  for (int b = 0; b < kBins; ++b) {
    const auto i = static_cast<std::size_t>(b);
    if (count_[i] == 0) continue;
    const double n = static_cast<double>(count_[i]);
    out.x.push_back(kScaleDegS * std::sinh((b + 0.5 - kBins / 2.0) * kBinWidth));
    out.mean_pa.push_back(sum_[i] / n);
    out.rms_pa.push_back(std::sqrt(sum2_[i] / n));
    out.samples.push_back(count_[i]);
  }
  return out;
}

VelocityBand VelocityProfile::band(double noise_sigma_pa) const {
  VelocityBand out;
  if (all_count_ == 0 || !(noise_sigma_pa > 0)) return out;
  const double s2 = noise_sigma_pa * noise_sigma_pa, n_all = static_cast<double>(all_count_);
  const double excess_all = all_sum2_ - n_all * s2;
  if (!(excess_all > 0)) return out;
  for (std::size_t i = 0; i < kBandsDegS.size(); ++i) {
    const double n_in = static_cast<double>(in_count_[i]), n_out = n_all - n_in;
    if (n_in < 1 || n_out < 1) continue;
    const double ms_in = in_sum2_[i] / n_in, ms_out = (all_sum2_ - in_sum2_[i]) / n_out;
    const double excess_in = in_sum2_[i] - n_in * s2;
    const double rows = n_in / n_all, share = excess_in / excess_all;
    if (rows <= kBandMaxRows && share >= kBandExcessShare && ms_in >= kBandContrast * ms_out && ms_in >= 4 * s2) {
      out = {kBandsDegS[i], std::sqrt(ms_in), std::sqrt(ms_out), rows, share};
      return out;
    }
  }
  for (std::size_t i = 0; i < kBandsDegS.size(); ++i) {
    const double np = static_cast<double>(pos_count_[i]), nn = static_cast<double>(neg_count_[i]);
    if (np < kFlipMinRows * n_all || nn < kFlipMinRows * n_all) continue;
    const double mp = pos_sum_[i] / np, mn = neg_sum_[i] / nn, m = (pos_sum_[i] + neg_sum_[i]) / (np + nn);
    const double split = np * (mp - m) * (mp - m) + nn * (mn - m) * (mn - m);
    if (std::abs(mp - mn) >= kFlipSigmas * noise_sigma_pa && split >= kFlipExcessShare * excess_all) {
      const double n_in = static_cast<double>(in_count_[i]), n_out = n_all - n_in;
      out.below_deg_s = kBandsDegS[i];
      out.rms_in_pa = std::sqrt(in_sum2_[i] / n_in);
      out.rms_out_pa = n_out > 0 ? std::sqrt((all_sum2_ - in_sum2_[i]) / n_out) : 0;
      out.rows_share = n_in / n_all;
      out.excess_share = split / excess_all;
      out.flips = true, out.mean_opening_pa = mp, out.mean_closing_pa = mn;
      return out;
    }
  }
  return out;
}

BandSplit split_at(const Binned& profile, double below_deg_s) {
  double sum2_in = 0, n_in = 0, sum2_out = 0, n_out = 0;
  for (std::size_t i = 0; i < profile.x.size(); ++i) {
    const double k = static_cast<double>(profile.samples[i]), s2 = k * profile.rms_pa[i] * profile.rms_pa[i];
    if (std::abs(profile.x[i]) < below_deg_s)
      sum2_in += s2, n_in += k;
    else
      sum2_out += s2, n_out += k;
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  return {n_in > 0 ? std::sqrt(sum2_in / n_in) : nan, n_out > 0 ? std::sqrt(sum2_out / n_out) : nan,
          n_in + n_out > 0 ? n_in / (n_in + n_out) : 0.0};
}

}  // namespace hil::analysis::detail
