#include "angle_signature.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace hil::analysis::detail {
namespace {

// A period is a ripple when its fit explains this many times the median of the periods around it
// (half to 1/1.3 and 1.3 to twice it): a broad, slow misfit against the angle (an offset, a wrong
// throat map) explains about as much at every nearby period; a ripple only at its own.
constexpr double kPeakOverNeighbours = 5;
// ... and at least half of the detrended bin means' power.
constexpr double kMinPowerShare = 0.5;
// ... with an amplitude of at least the noise RMS (a fit to the bins' noise and slow structure reached
// 0.7 kPa at 2 kPa of noise).
constexpr double kMinAmplitudeOfNoise = 1.0;
constexpr double kPeriodStep = 1.02;  // log grid of trial periods (2 %), refined around the best
constexpr double kMinPeriodBins = 4;
constexpr double kMinPeriods = 3;  // the span must hold at least three periods

struct Fit {
  double explained = 0, amplitude = 0, detrended_power = 0;
};

// Bin means m (NaN: empty bin) minus their moving average over one period, fitted by a sinusoid of
// that period (equal weight per occupied bin: the samples of one bin come from one dwell, so their
// number says little about their independence).
Fit fit_period(const std::vector<double>& m, const std::vector<double>& csum, const std::vector<double>& ccount,
               double period_bins) {
  const long n = static_cast<long>(m.size());
  const long half = std::max(1L, std::lround(period_bins / 2));
  double scc = 0, sss = 0, scs = 0, scd = 0, ssd = 0, sdd = 0;
  for (long i = 0; i < n; ++i) {
    if (std::isnan(m[static_cast<std::size_t>(i)])) continue;
    const long a = std::max(0L, i - half), b = std::min(n, i + half + 1);
    const double cnt = ccount[static_cast<std::size_t>(b)] - ccount[static_cast<std::size_t>(a)];
    const double ma = (csum[static_cast<std::size_t>(b)] - csum[static_cast<std::size_t>(a)]) / cnt;
    const double d = m[static_cast<std::size_t>(i)] - ma;
    const double ph = 2 * std::numbers::pi * static_cast<double>(i) / period_bins;
    const double c = std::cos(ph), s = std::sin(ph);
    scc += c * c, sss += s * s, scs += c * s, scd += c * d, ssd += s * d, sdd += d * d;
  }
  const double det = scc * sss - scs * scs;
  Fit f;
  f.detrended_power = sdd;
  if (!(det > 0)) return f;
  const double a = (sss * scd - scs * ssd) / det, b = (scc * ssd - scs * scd) / det;
  f.explained = a * scd + b * ssd;
  f.amplitude = std::hypot(a, b);
  return f;
}

}  // namespace

void AngleProfile::add(double drive_deg, double e_pa) {
  if (!std::isfinite(drive_deg) || !std::isfinite(e_pa) || std::abs(drive_deg) > kMaxAbsDeg) return;
  if (count_.empty()) {
    const auto bins = static_cast<std::size_t>(2 * kMaxAbsDeg / kBinDeg) + 1;
    sum_.assign(bins, 0.0), sum2_.assign(bins, 0.0), count_.assign(bins, 0);
  }
  const auto i = static_cast<std::size_t>((drive_deg + kMaxAbsDeg) / kBinDeg);
  sum_[i] += e_pa, sum2_[i] += e_pa * e_pa, ++count_[i];
}

Binned AngleProfile::binned() const {
  Binned out{"drive angle", "deg", {}, {}, {}, {}};
  std::size_t lo = count_.size(), hi = 0;
  for (std::size_t i = 0; i < count_.size(); ++i)
    if (count_[i]) lo = std::min(lo, i), hi = std::max(hi, i);
  if (lo > hi) return out;
  const std::size_t group = std::max<std::size_t>(1, (hi - lo + 1 + 59) / 60);
  for (std::size_t i = lo; i <= hi; i += group) {
    double s = 0, s2 = 0;
    std::size_t n = 0;
    for (std::size_t j = i; j < std::min(hi + 1, i + group); ++j) s += sum_[j], s2 += sum2_[j], n += count_[j];
    if (n < 10) continue;
    out.x.push_back((static_cast<double>(i) + 0.5 * static_cast<double>(group)) * kBinDeg - kMaxAbsDeg);
    out.mean_pa.push_back(s / static_cast<double>(n));
    out.rms_pa.push_back(std::sqrt(s2 / static_cast<double>(n)));
    out.samples.push_back(n);
  }
  return out;
}

AngleRipple AngleProfile::ripple(double noise_sigma_pa) const {
  AngleRipple out;
  std::size_t lo = count_.size(), hi = 0;
  for (std::size_t i = 0; i < count_.size(); ++i)
    if (count_[i]) lo = std::min(lo, i), hi = std::max(hi, i);
  if (lo > hi) return out;
  const std::size_t n = hi - lo + 1;
  out.span_deg = static_cast<double>(n) * kBinDeg;
  std::vector<double> m(n, std::numeric_limits<double>::quiet_NaN()), csum(n + 1, 0.0), ccount(n + 1, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t c = count_[lo + i];
    if (c) m[i] = sum_[lo + i] / static_cast<double>(c);
    csum[i + 1] = csum[i] + (c ? m[i] : 0.0);
    ccount[i + 1] = ccount[i] + (c ? 1.0 : 0.0);
  }
  const double max_period = static_cast<double>(n) / kMinPeriods;
  if (max_period < kMinPeriodBins) return out;
  std::vector<double> periods, explained;
  for (double p = kMinPeriodBins; p <= max_period; p *= kPeriodStep) {
    periods.push_back(p);
    explained.push_back(fit_period(m, csum, ccount, p).explained);
  }
  // The best period that stands out of its neighbourhood.
  double best_score = 0;
  std::size_t best = periods.size();
  for (std::size_t k = 0; k < periods.size(); ++k) {
    std::vector<double> around;
    for (std::size_t j = 0; j < periods.size(); ++j) {
      const double r = periods[j] / periods[k];
      if ((r >= 0.5 && r <= 1 / 1.3) || (r >= 1.3 && r <= 2)) around.push_back(explained[j]);
    }
    if (around.size() < 4) continue;
    std::nth_element(around.begin(), around.begin() + static_cast<std::ptrdiff_t>(around.size() / 2), around.end());
    const double median = around[around.size() / 2];
    if (!(explained[k] >= kPeakOverNeighbours * median)) continue;
    if (explained[k] > best_score) best_score = explained[k], best = k;
  }
  if (best == periods.size()) return out;
  // Refine the period on a finer grid around the best (0.2 % steps within one coarse step).
  double p_best = periods[best];
  Fit f_best = fit_period(m, csum, ccount, p_best);
  for (double p = periods[best] / kPeriodStep; p <= periods[best] * kPeriodStep; p *= 1.002) {
    const Fit f = fit_period(m, csum, ccount, p);
    if (f.explained > f_best.explained) f_best = f, p_best = p;
  }
  const double share = f_best.detrended_power > 0 ? f_best.explained / f_best.detrended_power : 0;
  if (share < kMinPowerShare || f_best.amplitude < kMinAmplitudeOfNoise * noise_sigma_pa) return out;
  out.period_deg = p_best * kBinDeg;
  out.amplitude_pa = f_best.amplitude;
  out.power_share = share;
  return out;
}

}  // namespace hil::analysis::detail
