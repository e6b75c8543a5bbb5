#include "hil/analysis/residuals.hpp"

#include "residual_analyzer.hpp"

namespace hil::analysis {

double fit_percent(double rss_pa2, double y_spread_pa, std::size_t n) {
  const double denom = y_spread_pa * std::sqrt(static_cast<double>(n));
  if (!(denom > 0)) return kNaN;
  return 100.0 * (1.0 - std::sqrt(rss_pa2) / denom);
}

// tau_int = 1 + 2 sum rho(l), truncated by Geyer's initial positive sequence.
double residual_detail::tau_from_acf(const std::vector<double>& rho) {
  double sum = 0;
  std::size_t m = 0;
  for (; 2 * m + 1 < rho.size(); ++m) {
    const double pair = rho[2 * m] + rho[2 * m + 1];
    if (pair <= 0) break;
    sum += pair;
  }
  return std::max(1.0, -1.0 + 2.0 * sum);
}

double integrated_autocorrelation_time(const std::vector<double>& e, std::size_t max_lag) {
  const std::size_t n = e.size();
  if (n < 4) return 1;
  const double mean = std::accumulate(e.begin(), e.end(), 0.0) / static_cast<double>(n);
  const std::size_t lags = std::min(max_lag, n - 1);
  // The circular correlation of n samples zero-padded to M equals the linear one at every lag l
  // with n + l <= M: padding to n + lags, not 2 n, is exact here and halves the memory of a long
  // residual in most cases (a diagnosis of an hour's run peaked on this buffer).
  const std::size_t nfft = detail::next_pow2(n + lags);
  detail::Fft fft(nfft);
  std::vector<cplx> a(nfft);
  for (std::size_t i = 0; i < n; ++i) a[i] = e[i] - mean;
  fft.forward(a);
  for (auto& x : a) x = std::norm(x);
  fft.inverse(a);
  std::vector<double> rho(lags + 1);
  const double r0 = a[0].real();
  if (!(r0 > 0)) return 1;
  for (std::size_t l = 0; l <= lags; ++l) rho[l] = a[l].real() / r0;
  return tau_from_acf(rho);
}

ResidualAnalyzer::ResidualAnalyzer(const AnalyzerOptions& options) : impl_(std::make_unique<Impl>(options)) {}
ResidualAnalyzer::~ResidualAnalyzer() = default;
void ResidualAnalyzer::add(const ResidualSample& s) { impl_->add(s); }
ResidualReport ResidualAnalyzer::finish() { return impl_->finish(); }

ResidualReport ResidualAnalyzer::Impl::finish() {
  ResidualReport r;
  r.rows = n;
  if (n == 0) return r;
  r.t0_s = t_first;
  r.duration_s = t_last - t_first;
  r.error = all.stats();
  r.rss_pa2 = all.se2;
  const double spread2 = std::max(0.0, syy - sy * sy / static_cast<double>(n));
  r.y_spread_pa = std::sqrt(spread2 / static_cast<double>(n));
  r.fit_pct = fit_percent(all.se2, r.y_spread_pa, n);
  r.noise = noise.finish();
  r.noise_sigma_pa = r.noise.sigma_pa;
  r.noise_method = r.noise.method;
  r.noise_floor_fit_pct = r.y_spread_pa > 0 ? 100.0 * (1.0 - r.noise_sigma_pa / r.y_spread_pa) : kNaN;

  // Regimes.
  const double N = static_cast<double>(n);
  auto regime = [&](std::string name, std::string what, const Acc& a) {
    r.regimes.push_back({std::move(name), std::move(what), a.stats(), static_cast<double>(a.n) / N});
  };
  regime("holding", "drive still (|velocity| < 0.5 deg/s over 10 ms)", motion[0]);
  regime("opening", "drive opening the valve (velocity > +0.5 deg/s)", motion[1]);
  regime("closing", "drive closing the valve (velocity < -0.5 deg/s)", motion[2]);
  regime("after_reversal", "first 0.5 s after the drive reverses (from its turning point; a reversal retreats > 0.1 deg)",
         after_rev);
  // Low/high pressure: split at the median measured pressure (from the fine histogram).
  {
    Acc lo, hi;
    std::size_t cum = 0, split = kPressureBins;
    for (std::size_t i = 0; i < kPressureBins; ++i) {
      cum += pbins[i].n;
      if (2 * cum >= n) {
        split = i;
        break;
      }
    }
    for (std::size_t i = 0; i < kPressureBins; ++i) (i <= split ? lo : hi).merge(pbins[i]);
    const double p_split = opt.pressure_lo_pa + (opt.pressure_hi_pa - opt.pressure_lo_pa) * (split + 1.0) / kPressureBins;
    regime("low_pressure", fmt("measured pressure below the median (%.3f MPa)", units::pa_to_mpa(p_split)), lo);
    regime("high_pressure", fmt("measured pressure above the median (%.3f MPa)", units::pa_to_mpa(p_split)), hi);
  }
  // Early/late: the first and second half of the run's windows.
  {
    Acc early, late;
    const double half = t_first + 0.5 * r.duration_s;
    for (std::size_t i = 0; i < windows.size(); ++i) {
      const double mid = t_first + (static_cast<double>(i) + 0.5) * win_width;
      (mid < half ? early : late).merge(windows[i].e);
    }
    regime("early", "first half of the run", early);
    regime("late", "second half of the run", late);
  }

  // Windows, worst, failing spans.
  r.window_width_s = win_width;
  static const char* kMotionNames[] = {"holding", "opening", "closing"};
  for (std::size_t i = 0; i < windows.size(); ++i) {
    const auto& w = windows[i];
    TimeWindow tw;
    tw.t0_s = t_first + static_cast<double>(i) * win_width;
    tw.t1_s = std::min(t_last, tw.t0_s + win_width);
    tw.error = w.e.stats();
    const auto m = std::max_element(w.motion.begin(), w.motion.end()) - w.motion.begin();
    tw.regime = kMotionNames[m];
    tw.burned_kg = w.burned_kg;
    r.windows.push_back(tw);
  }
  std::vector<std::size_t> order;
  std::size_t max_samples = 0;
  for (const auto& w : r.windows) max_samples = std::max(max_samples, w.error.samples);
  for (std::size_t i = 0; i < r.windows.size(); ++i)
    if (r.windows[i].error.samples * 4 >= max_samples && r.windows[i].error.samples >= 5) order.push_back(i);
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return r.windows[a].error.rmse_pa > r.windows[b].error.rmse_pa; });
  std::vector<bool> fail(r.windows.size(), false);
  {
    const double floor_rms = 3 * r.noise_sigma_pa;
    for (std::size_t i : order) {
      const double rms = r.windows[i].error.rmse_pa;
      if (rms >= std::max(floor_rms, 1.5 * r.error.rmse_pa)) fail[i] = true;
    }
    for (std::size_t j = 0; j < std::min<std::size_t>(3, order.size()); ++j) {
      const double rms = r.windows[order[j]].error.rmse_pa;
      if (rms >= std::max(floor_rms, 1.2 * r.error.rmse_pa)) fail[order[j]] = true;
    }
    for (std::size_t i = 0; i < fail.size(); ++i) {
      if (!fail[i]) continue;
      if (!r.failing.empty() && std::abs(r.failing.back().second - r.windows[i].t0_s) < 1e-9) {
        r.failing.back().second = r.windows[i].t1_s;
      } else {
        r.failing.push_back({r.windows[i].t0_s, r.windows[i].t1_s});
      }
    }
  }
  // The worst windows, one per failure: a listed window hides the rest of its failing span (or,
  // outside any, its two neighbours).
  std::vector<bool> hidden(r.windows.size(), false);
  for (std::size_t i : order) {
    if (r.worst.size() >= 8) break;
    if (hidden[i]) continue;
    r.worst.push_back(i);
    hidden[i] = true;
    if (i > 0) hidden[i - 1] = true;
    if (i + 1 < hidden.size()) hidden[i + 1] = true;
    for (std::size_t j = i; fail[i] && j < fail.size() && fail[j]; ++j) hidden[j] = true;
    for (std::size_t j = i; fail[i] && j-- > 0 && fail[j];) hidden[j] = true;
  }
  r.reversals = reversals;
  r.motion_cycle_hz = r.duration_s > 0 && reversals >= 2 ? static_cast<double>(reversals) / (2 * r.duration_s) : 0;
  r.reference_cycle_hz = r.duration_s > 0 && ref_reversals >= 2 ? static_cast<double>(ref_reversals) / (2 * r.duration_s) : 0;

  finish_diagnostics(r);
  find_segments(r);
  describe(r);
  if (opt.keep_series) {
    r.series = plotted.take();
  }
  return r;
}

}  // namespace hil::analysis
