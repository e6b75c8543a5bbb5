// The residual analyser's diagnostics: correlations, whiteness, spectrum and its named peaks.
#include "residual_analyzer.hpp"

namespace hil::analysis {

void ResidualAnalyzer::Impl::finish_diagnostics(ResidualReport& r) {
  Diagnostics& d = r.diagnostics;
  std::vector<double> dts = first_dts;
  if (!dts.empty()) {
    std::nth_element(dts.begin(), dts.begin() + static_cast<long>(dts.size() / 2), dts.end());
    d.dt_s = dts[dts.size() / 2];
  }
  if (!(d.dt_s > 0)) d.dt_s = 1e-3;
  process_block();

  // Autocorrelation and whiteness.
  const double N = static_cast<double>(corr_n);
  if (corr_n >= 16 && acc_ee[0] > 0) {
    const std::size_t lags = std::min(kMaxLag, corr_n - 1);
    std::vector<double> rho(lags + 1);
    for (std::size_t l = 0; l <= lags; ++l) rho[l] = acc_ee[l] / acc_ee[0];
    d.acf_bound = kZ99 / std::sqrt(N);
    std::size_t outside = 0, tested = 0;
    for (std::size_t l = 1; l <= std::min(kWhitenessLags, lags); ++l, ++tested)
      if (std::abs(rho[l]) > d.acf_bound) ++outside;
    d.acf_outside_share = tested ? static_cast<double>(outside) / static_cast<double>(tested) : 0;
    d.white = d.acf_outside_share <= 0.05;
    d.tau_int_samples = tau_from_acf(rho);
    d.n_eff = N / d.tau_int_samples;
    for (std::size_t l = 0; l <= lags; ++l) {
      d.acf_lag_s.push_back(static_cast<double>(l) * d.dt_s);
      d.acf.push_back(rho[l]);
    }
    // Cross-correlation with the input (drive increments).
    if (acc_uu[0] > 0) {
      double bartlett = 1;
      for (std::size_t l = 1; l <= lags; ++l) bartlett += 2 * rho[l] * acc_uu[l] / acc_uu[0];
      d.xcf_bound = kZ99 * std::sqrt(std::max(bartlett, 1.0)) / std::sqrt(N);
      const double norm = std::sqrt(acc_ee[0] * acc_uu[0]);
      std::size_t out = 0, tested_x = 0;
      for (long l = -static_cast<long>(lags); l <= static_cast<long>(lags); ++l) {
        const double v = acc_ue[static_cast<std::size_t>(static_cast<long>(kMaxLag) + l)] / norm;
        d.xcf_lag_s.push_back(static_cast<double>(l) * d.dt_s);
        d.xcf.push_back(v);
        if (std::abs(v) > d.xcf_max_abs) d.xcf_max_abs = std::abs(v), d.xcf_max_lag_s = static_cast<double>(l) * d.dt_s;
        if (l >= 0 && l <= static_cast<long>(kWhitenessLags)) {
          ++tested_x;
          if (std::abs(v) > d.xcf_bound) ++out;
        }
      }
      d.input_correlated = tested_x > 0 && static_cast<double>(out) / static_cast<double>(tested_x) > 0.05;
    }
  } else {
    d.n_eff = N;
  }

  // Spectrum.
  if (segments == 0 && n >= 16) {
    std::size_t len = 16;
    while (len * 2 <= std::min(n, seg)) len *= 2;
    process_segment(len);
  }
  if (segments > 0) {
    const double fs = 1.0 / d.dt_s;
    const double scale = 1.0 / (fs * hann_power * static_cast<double>(segments)) / (units::kPaPerKpa * units::kPaPerKpa);
    double total = 0, slow = 0;
    for (std::size_t k = 0; k <= seg / 2; ++k) {
      double p = psd_acc[k] * scale * ((k == 0 || k == seg / 2) ? 1.0 : 2.0);
      const double f = static_cast<double>(k) * fs / static_cast<double>(seg);
      d.psd_hz.push_back(f);
      d.psd_kpa2_per_hz.push_back(p);
      total += p;
      if (f < kSlowHz) slow += p;
    }
    d.low_frequency_share = total > 0 ? slow / total : 0;
    name_peaks(r);
  }

  // Event-locked residual after reversals.
  for (std::size_t b = 0; b < locked_open.size(); ++b) {
    d.since_reversal_s.push_back((static_cast<double>(b) + 0.5) * kLockedBinS);
    d.after_opening_mean_pa.push_back(locked_open[b].n ? locked_open[b].se / static_cast<double>(locked_open[b].n) : kNaN);
    d.after_closing_mean_pa.push_back(locked_close[b].n ? locked_close[b].se / static_cast<double>(locked_close[b].n) : kNaN);
  }

  // Binned views.
  auto push = [](Binned& b, double x, const Acc& a) {
    b.x.push_back(x);
    b.mean_pa.push_back(a.se / static_cast<double>(a.n));
    b.rms_pa.push_back(std::sqrt(a.se2 / static_cast<double>(a.n)));
    b.samples.push_back(a.n);
  };
  d.vs_pressure = {"measured pressure", "MPa", {}, {}, {}, {}};
  {
    // Re-bin the fine histogram over the occupied range into about 25 bins.
    std::size_t lo = kPressureBins, hi = 0;
    for (std::size_t i = 0; i < kPressureBins; ++i)
      if (pbins[i].n) lo = std::min(lo, i), hi = std::max(hi, i);
    if (lo <= hi) {
      const std::size_t group = std::max<std::size_t>(1, (hi - lo + 1 + 24) / 25);
      for (std::size_t i = lo; i <= hi; i += group) {
        Acc a;
        for (std::size_t j = i; j < std::min(hi + 1, i + group); ++j) a.merge(pbins[j]);
        if (a.n < 10) continue;
        const double mid = (static_cast<double>(i) + 0.5 * static_cast<double>(group)) / kPressureBins;
        push(d.vs_pressure, units::pa_to_mpa(opt.pressure_lo_pa + mid * (opt.pressure_hi_pa - opt.pressure_lo_pa)), a);
      }
    }
  }
  d.vs_dpdt = {"model dp/dt", "MPa/s", {}, {}, {}, {}};
  for (int i = 0; i < kDpdtBins; ++i) {
    const Acc& a = dpdt_bins[static_cast<std::size_t>(i)];
    if (a.n < 10) continue;
    const double u = (i + 0.5 - kDpdtBins / 2.0) * kDpdtBinWidth;
    push(d.vs_dpdt, units::pa_to_mpa(kDpdtScalePaS * std::sinh(u)), a);
  }
  d.vs_time = {"time", "s", {}, {}, {}, {}};
  d.vs_burned = {"burned propellant (model)", "kg", {}, {}, {}, {}};
  for (std::size_t i = 0; i < windows.size(); ++i) {
    if (windows[i].e.n == 0) continue;
    push(d.vs_time, r.windows[i].t0_s + 0.5 * win_width, windows[i].e);
    push(d.vs_burned, windows[i].burned_kg, windows[i].e);
  }
  d.vs_drive_angle = angle.binned();
  const detail::AngleRipple ripple = angle.ripple(r.noise_sigma_pa);
  d.angle_ripple_period_deg = ripple.period_deg;
  d.angle_ripple_kpa = ripple.amplitude_pa / units::kPaPerKpa;
  d.angle_ripple_share = ripple.power_share;
  d.vs_drive_velocity = velocity.binned();
  const detail::VelocityBand band = velocity.band(r.noise_sigma_pa);
  d.velocity_band_deg_s = band.below_deg_s;
  d.velocity_band_rms_kpa = band.rms_in_pa / units::kPaPerKpa;
  d.velocity_outside_rms_kpa = band.rms_out_pa / units::kPaPerKpa;
  d.velocity_band_rows_share = band.rows_share;
  d.velocity_band_excess_share = band.excess_share;
  d.velocity_band_flips = band.flips;
  d.velocity_band_opening_kpa = band.mean_opening_pa / units::kPaPerKpa;
  d.velocity_band_closing_kpa = band.mean_closing_pa / units::kPaPerKpa;
}

void ResidualAnalyzer::Impl::name_peaks(ResidualReport& r) {
  Diagnostics& d = r.diagnostics;
  const auto& p = d.psd_kpa2_per_hz;
  const std::size_t m = p.size();
  if (m < 8) return;
  const double df = d.psd_hz[1];
  const double total = std::accumulate(p.begin(), p.end(), 0.0);
  if (!(total > 0)) return;
  struct Cand {
    std::size_t k;
    double share;
  };
  std::vector<Cand> found;
  for (std::size_t k = 3; k + 1 < m; ++k) {
    if (p[k] < p[k - 1] || p[k] < p[k + 1]) continue;
    std::vector<double> around;
    for (std::size_t j = (k > 16 ? k - 16 : 0); j < std::min(m, k + 17); ++j)
      if (j + 2 < k || j > k + 2) around.push_back(p[j]);
    if (around.empty()) continue;
    std::nth_element(around.begin(), around.begin() + static_cast<long>(around.size() / 2), around.end());
    const double base = around[around.size() / 2];
    if (!(p[k] > 10 * base)) continue;
    double share = 0;
    for (std::size_t j = k - 2; j <= std::min(m - 1, k + 2); ++j) share += p[j];
    share /= total;
    if (share >= 0.01) found.push_back({k, share});
  }
  std::sort(found.begin(), found.end(), [](const Cand& a, const Cand& b) { return a.share > b.share; });
  if (found.size() > 5) found.resize(5);
  auto harmonic = [&](double f, double base_hz) -> int {
    if (!(base_hz > 0)) return 0;
    const double k = std::round(f / base_hz);
    if (k < 1 || k > 10) return 0;  // beyond the 10th harmonic a match is a coincidence
    return std::abs(f - k * base_hz) <= std::max(1.5 * df, 0.03 * f) ? static_cast<int>(k) : 0;
  };
  // Does the drive move at this frequency too (a peak in its increments' spectrum)?
  auto drive_peak = [&](std::size_t k) {
    if (psd_u_acc.size() != m) return false;
    std::vector<double> around;
    for (std::size_t j = (k > 16 ? k - 16 : 0); j < std::min(m, k + 17); ++j)
      if (j + 2 < k || j > k + 2) around.push_back(psd_u_acc[j]);
    if (around.empty()) return false;
    std::nth_element(around.begin(), around.begin() + static_cast<long>(around.size() / 2), around.end());
    double top = 0;
    for (std::size_t j = k - 1; j <= std::min(m - 1, k + 1); ++j) top = std::max(top, psd_u_acc[j]);
    return top > 10 * around[around.size() / 2];
  };
  for (const auto& c : found) {
    SpectrumPeak pk;
    pk.hz = d.psd_hz[c.k];
    pk.power_share = c.share;
    const double mains50 = std::round(pk.hz / 50), mains60 = std::round(pk.hz / 60);
    const bool driven = drive_peak(c.k);
    if (int h2 = harmonic(pk.hz, r.reference_cycle_hz)) {
      pk.name = fmt("harmonic %.0f of the reference cycle (%.3g Hz): the model answers the reference's steps wrongly", h2,
                    r.reference_cycle_hz);
    } else if (mains50 >= 1 && std::abs(pk.hz - 50 * mains50) <= std::max(df, 0.5)) {
      pk.name = fmt("mains hum (%.0f x 50 Hz): electrical pickup on the transducer", mains50);
    } else if (mains60 >= 1 && std::abs(pk.hz - 60 * mains60) <= std::max(df, 0.5)) {
      pk.name = fmt("mains hum (%.0f x 60 Hz): electrical pickup on the transducer", mains60);
    } else if (int h = harmonic(pk.hz, r.motion_cycle_hz); h && r.motion_cycle_hz < 2 && r.reference_cycle_hz <= 0) {
      pk.name = fmt("harmonic %.0f of the motion cycle (%.3g Hz: the drive reverses every %.3g s on average)", h,
                    r.motion_cycle_hz, 0.5 / r.motion_cycle_hz);
    } else if (driven) {
      pk.name =
          fmt("periodic component at %.3g Hz (period %.3g s), not in the reference; the drive moves at this "
              "frequency too (the controller chasing it): an oscillation the model lacks (combustion, structure, "
              "a disturbance), or a limit cycle",
              pk.hz, 1.0 / pk.hz);
    } else {
      pk.name =
          fmt("periodic component at %.3g Hz (period %.3g s) that no input carries: an oscillation the model "
              "lacks (combustion, structure, a disturbance)",
              pk.hz, 1.0 / pk.hz);
    }
    d.peaks.push_back(pk);
  }
}

}  // namespace hil::analysis
