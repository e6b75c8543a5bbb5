#include "hil/analysis/residuals.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <cstdio>
#include <limits>
#include <numbers>
#include <numeric>
#include <stdexcept>

#include "angle_signature.hpp"
#include "fft.hpp"
#include "hil/minmax_decimator.hpp"
#include "hil/units.hpp"

#include "text.hpp"

namespace hil::analysis {
namespace {

using cplx = std::complex<double>;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// --- tunables, each with its reason -------------------------------------------------------------
constexpr double kVelocityWindowS = 0.010;                          // drive velocity over 10 ms: smooths encoder steps
constexpr double kMotionThresholdRadS = 0.5 * units::kRadPerDeg;    // 0.5 deg/s: noise creep is slower
constexpr double kReversalHysteresisRad = 0.1 * units::kRadPerDeg;  // a reversal retreats > 0.1 deg
constexpr double kAfterReversalS = 0.5;                             // "the first 0.5 s after each reversal": where backlash shows
constexpr double kLockedSpanS = 1.0, kLockedBinS = 0.01;            // event-locked residual after reversals
constexpr std::size_t kMaxWindows = 512;                            // time windows merge pairwise beyond this
constexpr std::size_t kBlock = 16384;                               // correlation block (zero-padded to 2x)
constexpr std::size_t kMaxLag = 1000;                               // correlation lags kept
constexpr std::size_t kWhitenessLags = 200;                         // lags 1..200 tested against the 99 % bounds
constexpr double kZ99 = 2.576;
constexpr std::size_t kPressureBins = 256;
constexpr double kDpdtScalePaS = 5e4;  // asinh bins of dp/dt around 0.05 MPa/s
constexpr double kDpdtBinWidth = 0.5;
constexpr int kDpdtBins = 40;
constexpr std::size_t kSeriesBuckets = 4000;
constexpr double kSlowHz = 0.5;

struct Acc {  // error accumulator
  std::size_t n = 0;
  double se = 0, se2 = 0, max_abs = 0, t_max = 0;
  void add(double t, double e) {
    ++n;
    se += e;
    se2 += e * e;
    if (std::abs(e) > max_abs) max_abs = std::abs(e), t_max = t;
  }
  void merge(const Acc& o) {
    n += o.n;
    se += o.se;
    se2 += o.se2;
    if (o.max_abs > max_abs) max_abs = o.max_abs, t_max = o.t_max;
  }
  ErrorStats stats() const {
    ErrorStats s;
    s.samples = n;
    if (n == 0) return s;
    s.rmse_pa = std::sqrt(se2 / static_cast<double>(n));
    s.bias_pa = se / static_cast<double>(n);
    s.max_abs_pa = max_abs;
    s.t_at_max_s = t_max;
    return s;
  }
};

struct WindowAcc {
  Acc e;
  std::array<std::size_t, 3> motion{};  // holding, opening, closing
  double burned_kg = 0;
  void merge(const WindowAcc& o) {
    e.merge(o.e);
    for (int i = 0; i < 3; ++i) motion[i] += o.motion[i];
    burned_kg = std::max(burned_kg, o.burned_kg);
  }
};

// The plotted series (measured, model, residual, drive, reference): min/max decimated as the rows
// stream by, over shared buckets so they share their times (hil/minmax_decimator.hpp).
class SeriesDecimator {
 public:
  void add(double t, const std::array<double, 5>& values) { d_.add(t, values); }
  ReportSeries take() const {
    std::vector<double> t;
    std::vector<std::vector<double>> v;
    d_.take(t, v);
    ReportSeries out;
    TimeSeries* series[] = {&out.measured_mpa, &out.model_mpa, &out.residual_kpa, &out.drive_deg, &out.reference_mpa};
    for (std::size_t i = 0; i < std::size(series); ++i) {
      // A column without a finite value (a measurement without a reference) stays empty: no line.
      if (std::none_of(v[i].begin(), v[i].end(), [](double x) { return std::isfinite(x); })) continue;
      series[i]->t_s = t;
      series[i]->value = std::move(v[i]);
    }
    return out;
  }

 private:
  MinMaxDecimator d_{kSeriesBuckets, 5};
};

std::string fmt(const char* f, double a) {
  char b[512];
  std::snprintf(b, sizeof b, f, a);
  return b;
}
std::string fmt(const char* f, double a, double b2) {
  char b[512];
  std::snprintf(b, sizeof b, f, a, b2);
  return b;
}
std::string fmt(const char* f, double a, double b2, double c) {
  char b[512];
  std::snprintf(b, sizeof b, f, a, b2, c);
  return b;
}

}  // namespace

double fit_percent(double rss_pa2, double y_spread_pa, std::size_t n) {
  const double denom = y_spread_pa * std::sqrt(static_cast<double>(n));
  if (!(denom > 0)) return kNaN;
  return 100.0 * (1.0 - std::sqrt(rss_pa2) / denom);
}

namespace {

// tau_int = 1 + 2 sum rho(l), truncated by Geyer's initial positive sequence.
double tau_from_acf(const std::vector<double>& rho) {
  double sum = 0;
  std::size_t m = 0;
  for (; 2 * m + 1 < rho.size(); ++m) {
    const double pair = rho[2 * m] + rho[2 * m + 1];
    if (pair <= 0) break;
    sum += pair;
  }
  return std::max(1.0, -1.0 + 2.0 * sum);
}

}  // namespace

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

namespace {
void find_segments(ResidualReport& r);  // change points of the residual's level (defined below)
}  // namespace

struct ResidualAnalyzer::Impl {
  detail::AngleProfile angle;  // the residual against the drive angle
  AnalyzerOptions opt;

  // Totals.
  std::size_t n = 0;
  double t_first = 0, t_last = 0;
  Acc all;
  double y0 = 0, sy = 0, syy = 0;
  NoiseEstimator noise;  // the measurement noise as a process (noise_model.hpp)
  std::vector<double> first_dts;

  // Motion classification (from the drive angle).
  std::array<std::pair<double, double>, 64> ring{};
  std::size_t ring_n = 0, ring_head = 0;
  int dir = 0;  // hysteresis direction: +1 opening, -1 closing, 0 not yet moved
  double ext = 0, amin = 0, amax = 0;
  double ext_t = 0;  // time of the extreme `ext`
  double last_rev_t = -1e300;
  std::vector<std::pair<double, double>> recent = std::vector<std::pair<double, double>>(4096);  // (t, e)
  std::size_t recent_head = 0, recent_n = 0;
  int last_rev_dir = 0;
  std::size_t reversals = 0;
  double drive_prev = kNaN;

  // Reference reversals (for naming spectrum peaks).
  int ref_dir = 0;
  double ref_ext = 0;
  std::size_t ref_reversals = 0;

  std::array<Acc, 3> motion{};  // holding, opening, closing
  Acc after_rev;
  std::vector<Acc> pbins = std::vector<Acc>(kPressureBins);
  std::vector<Acc> dpdt_bins = std::vector<Acc>(kDpdtBins);
  double yhat_prev = kNaN, t_prev = kNaN;
  std::vector<Acc> locked_open, locked_close;

  // Windows.
  double win_width = 0.05;
  std::vector<WindowAcc> windows;

  // Correlations by blocks.
  std::vector<double> be, bu;
  std::vector<double> acc_ee = std::vector<double>(kMaxLag + 1), acc_uu = std::vector<double>(kMaxLag + 1);
  std::vector<double> acc_ue = std::vector<double>(2 * kMaxLag + 1);
  std::size_t corr_n = 0;

  // Welch spectrum.
  std::size_t seg = 4096;
  std::vector<double> ring_e, ring_u;
  std::size_t ring_e_count = 0, since_seg = 0, segments = 0;
  std::vector<double> psd_acc, psd_u_acc;
  std::vector<double> hann;
  double hann_power = 0;

  SeriesDecimator plotted;

  explicit Impl(const AnalyzerOptions& o) : opt(o) {
    const std::size_t locked_bins = static_cast<std::size_t>(std::lround(kLockedSpanS / kLockedBinS));
    locked_open.resize(locked_bins);
    locked_close.resize(locked_bins);
    if (o.expected_duration_s > 0) win_width = std::max(1e-3, o.expected_duration_s / 120.0);
    if (o.expected_rows > 0) {
      seg = 256;
      while (seg < 4096 && seg * 16 <= o.expected_rows) seg *= 2;
    }
    ring_e.assign(seg, 0.0);
    ring_u.assign(seg, 0.0);
    psd_acc.assign(seg / 2 + 1, 0.0);
    psd_u_acc.assign(seg / 2 + 1, 0.0);
    hann.resize(seg);
    for (std::size_t i = 0; i < seg; ++i) {
      hann[i] = 0.5 - 0.5 * std::cos(2 * std::numbers::pi * static_cast<double>(i) / static_cast<double>(seg));
      hann_power += hann[i] * hann[i];
    }
    be.reserve(kBlock);
    bu.reserve(kBlock);
  }

  int classify_motion(double t, double a) {
    ring[ring_head] = {t, a};
    ring_head = (ring_head + 1) % ring.size();
    ring_n = std::min(ring_n + 1, ring.size());
    // Velocity over the last ~10 ms.
    double v = 0;
    for (std::size_t back = 1; back < ring_n; ++back) {
      const auto& old = ring[(ring_head + ring.size() - 1 - back) % ring.size()];
      if (t - old.first >= kVelocityWindowS || back + 1 == ring_n) {
        if (t > old.first) v = (a - old.second) / (t - old.first);
        break;
      }
    }
    // Reversals with angle hysteresis.
    if (n == 0) amin = amax = a;
    if (dir == 0) {
      amin = std::min(amin, a);
      amax = std::max(amax, a);
      if (a - amin > kReversalHysteresisRad)
        dir = +1, ext = a, ext_t = t;
      else if (amax - a > kReversalHysteresisRad)
        dir = -1, ext = a, ext_t = t;
    } else if (dir > 0) {
      if (a >= ext) ext = a, ext_t = t;
      if (a < ext - kReversalHysteresisRad) reversal(-1, a, t);
    } else {
      if (a <= ext) ext = a, ext_t = t;
      if (a > ext + kReversalHysteresisRad) reversal(+1, a, t);
    }
    return v > kMotionThresholdRadS ? 1 : v < -kMotionThresholdRadS ? 2 : 0;
  }

  // A reversal detected at t_now: the drive left its extreme at ext_t. The rows since then were
  // seen before the reversal was known; count them into the after-reversal views now.
  void reversal(int new_dir, double a, double t_now) {
    const double t_rev = ext_t;
    dir = new_dir, ext = a, ext_t = t_now;
    last_rev_t = t_rev, last_rev_dir = new_dir, ++reversals;
    for (std::size_t back = 0; back < recent_n; ++back) {
      const auto& [t, e] = recent[(recent_head + recent.size() - 1 - back) % recent.size()];
      if (t < t_rev) break;
      add_after_reversal(t, e);
    }
  }

  void add_after_reversal(double t, double e) {
    const double since = t - last_rev_t;
    if (since < kAfterReversalS) after_rev.add(t, e);
    if (since < kLockedSpanS) {
      const auto b = static_cast<std::size_t>(since / kLockedBinS);
      if (b < locked_open.size()) (last_rev_dir > 0 ? locked_open : locked_close)[b].add(t, e);
    }
  }

  void track_reference(double p) {
    if (!std::isfinite(p)) return;
    constexpr double h = 1e3;  // 1 kPa
    if (ref_dir == 0) {
      if (n == 0) ref_ext = p;
      if (p > ref_ext + h)
        ref_dir = +1, ref_ext = p;
      else if (p < ref_ext - h)
        ref_dir = -1, ref_ext = p;
    } else if (ref_dir > 0) {
      ref_ext = std::max(ref_ext, p);
      if (p < ref_ext - h) ref_dir = -1, ref_ext = p, ++ref_reversals;
    } else {
      ref_ext = std::min(ref_ext, p);
      if (p > ref_ext + h) ref_dir = +1, ref_ext = p, ++ref_reversals;
    }
  }

  void add_window(double t, double e, int motion_class, double burned) {
    auto index = static_cast<std::size_t>(std::max(0.0, std::floor((t - t_first) / win_width)));
    while (index >= kMaxWindows) {
      std::vector<WindowAcc> merged;
      for (std::size_t i = 0; i < windows.size(); i += 2) {
        WindowAcc w = windows[i];
        if (i + 1 < windows.size()) w.merge(windows[i + 1]);
        merged.push_back(w);
      }
      windows = std::move(merged);
      win_width *= 2;
      index = static_cast<std::size_t>(std::floor((t - t_first) / win_width));
    }
    if (windows.size() <= index) windows.resize(index + 1);
    WindowAcc& w = windows[index];
    w.e.add(t, e);
    ++w.motion[static_cast<std::size_t>(motion_class)];
    w.burned_kg = burned;
  }

  void process_block() {
    const std::size_t m = be.size();
    if (m < 16) return;
    const double mean_e = std::accumulate(be.begin(), be.end(), 0.0) / static_cast<double>(m);
    const double mean_u = std::accumulate(bu.begin(), bu.end(), 0.0) / static_cast<double>(m);
    const std::size_t nfft = detail::next_pow2(2 * m);
    const detail::Fft fft(nfft);
    std::vector<cplx> z(nfft);
    for (std::size_t i = 0; i < m; ++i) z[i] = {be[i] - mean_e, bu[i] - mean_u};
    fft.forward(z);
    std::vector<cplx> auto_spec(nfft), cross(nfft);
    for (std::size_t k = 0; k < nfft; ++k) {
      const cplx zk = z[k], zn = std::conj(z[(nfft - k) % nfft]);
      const cplx E = 0.5 * (zk + zn), U = cplx(0, -0.5) * (zk - zn);
      auto_spec[k] = cplx(std::norm(E), std::norm(U));
      cross[k] = std::conj(U) * E;
    }
    fft.inverse(auto_spec);
    fft.inverse(cross);
    const std::size_t lags = std::min(kMaxLag, m - 1);
    for (std::size_t l = 0; l <= lags; ++l) {
      acc_ee[l] += auto_spec[l].real();
      acc_uu[l] += auto_spec[l].imag();
      acc_ue[kMaxLag + l] += cross[l].real();                    // sum u(k) e(k + l)
      if (l > 0) acc_ue[kMaxLag - l] += cross[nfft - l].real();  // sum u(k) e(k - l)
    }
    corr_n += m;
    be.clear();
    bu.clear();
  }

  void process_segment(std::size_t len) {
    // The last `len` samples of the ring, Hann windowed.
    // Residual and drive increments together: z = e + i u, separated after the transform.
    const detail::Fft fft(seg);
    std::vector<cplx> a(seg);
    const std::size_t start = (ring_e_count + seg - len) % seg;  // ring_e_count: next write index
    for (std::size_t i = 0; i < len; ++i) {
      const std::size_t j = (start + i) % seg;
      a[i] = cplx(ring_e[j], ring_u[j]) * hann[i * seg / len];
    }
    fft.forward(a);
    const double scale = static_cast<double>(seg) / static_cast<double>(len);
    for (std::size_t k = 0; k <= seg / 2; ++k) {
      const cplx zk = a[k], zn = std::conj(a[(seg - k) % seg]);
      psd_acc[k] += std::norm(0.5 * (zk + zn)) * scale;
      psd_u_acc[k] += std::norm(cplx(0, -0.5) * (zk - zn)) * scale;
    }
    ++segments;
  }

  void add(const ResidualSample& s) {
    const double e = s.y_pa - s.yhat_pa;
    if (n == 0) {
      t_first = s.t_s;
      y0 = s.y_pa;
    } else if (first_dts.size() < 2001) {
      first_dts.push_back(s.t_s - t_last);
    }
    all.add(s.t_s, e);
    sy += s.y_pa - y0;
    syy += (s.y_pa - y0) * (s.y_pa - y0);
    noise.add(s.t_s, s.y_pa);

    angle.add(units::rad_to_deg(s.drive_rad), e);
    const int motion_class = classify_motion(s.t_s, s.drive_rad);
    track_reference(s.p_ref_pa);
    motion[static_cast<std::size_t>(motion_class)].add(s.t_s, e);
    add_after_reversal(s.t_s, e);
    recent[recent_head] = {s.t_s, e};
    recent_head = (recent_head + 1) % recent.size();
    recent_n = std::min(recent_n + 1, recent.size());
    const double pf = (s.y_pa - opt.pressure_lo_pa) / (opt.pressure_hi_pa - opt.pressure_lo_pa);
    pbins[static_cast<std::size_t>(std::clamp(pf * kPressureBins, 0.0, kPressureBins - 1.0))].add(s.t_s, e);
    if (std::isfinite(yhat_prev) && s.t_s > t_prev) {
      const double dpdt = (s.yhat_pa - yhat_prev) / (s.t_s - t_prev);
      const double u = std::asinh(dpdt / kDpdtScalePaS) / kDpdtBinWidth + kDpdtBins / 2.0;
      dpdt_bins[static_cast<std::size_t>(std::clamp(u, 0.0, kDpdtBins - 1.0))].add(s.t_s, e);
    }
    yhat_prev = s.yhat_pa;
    t_prev = s.t_s;
    add_window(s.t_s, e, motion_class, s.burned_kg);

    // Correlation blocks: residual and drive increments.
    const double du = std::isfinite(drive_prev) ? s.drive_rad - drive_prev : 0.0;
    be.push_back(e);
    bu.push_back(du);
    drive_prev = s.drive_rad;
    if (be.size() == kBlock) process_block();

    // Welch segments.
    ring_e[ring_e_count % seg] = e;
    ring_u[ring_e_count % seg] = du;
    ring_e_count = (ring_e_count + 1) % seg;
    ++since_seg;
    if (n + 1 >= seg && since_seg >= seg / 2) {
      process_segment(seg);
      since_seg = 0;
    }

    if (opt.keep_series) {
      plotted.add(s.t_s, {units::pa_to_mpa(s.y_pa), units::pa_to_mpa(s.yhat_pa), e / units::kPaPerKpa,
                          units::rad_to_deg(s.drive_rad), units::pa_to_mpa(s.p_ref_pa)});
    }
    t_last = s.t_s;
    ++n;
  }

  ResidualReport finish();
  void finish_diagnostics(ResidualReport& r);
  void name_peaks(ResidualReport& r);
  void describe(ResidualReport& r);
};

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

namespace {

// Binary segmentation of the windows' mean square (see kChangeRmsRatio). Windows with fewer than
// a quarter of the fullest window's samples (a dropout) join their neighbours.
void find_segments(ResidualReport& r) {
  const auto& w = r.windows;
  if (w.empty()) return;
  std::size_t max_samples = 0;
  for (const auto& x : w) max_samples = std::max(max_samples, x.error.samples);
  std::vector<double> sum_sq(w.size() + 1, 0.0), count(w.size() + 1, 0.0);  // prefix sums
  for (std::size_t i = 0; i < w.size(); ++i) {
    const double n = static_cast<double>(w[i].error.samples);
    sum_sq[i + 1] = sum_sq[i] + w[i].error.rmse_pa * w[i].error.rmse_pa * n;
    count[i + 1] = count[i] + n;
  }
  auto ms = [&](std::size_t a, std::size_t b) {  // windows [a, b)
    const double n = count[b] - count[a];
    return n > 0 ? (sum_sq[b] - sum_sq[a]) / n : 0.0;
  };
  auto usable = [&](std::size_t i) { return w[i].error.samples * 4 >= max_samples; };
  std::vector<std::size_t> cuts = {0, w.size()};
  while (cuts.size() < kMaxChangePoints + 2) {
    // The best cut over all segments: largest likelihood gain of a piecewise-constant variance.
    double best_gain = 0;
    std::size_t best_cut = 0;
    for (std::size_t s = 0; s + 1 < cuts.size(); ++s) {
      const std::size_t a = cuts[s], b = cuts[s + 1];
      const double n = count[b] - count[a], m = ms(a, b);
      if (m <= 0) continue;
      for (std::size_t c = a + 2; c + 2 <= b; ++c) {
        if (!usable(c) || !usable(c - 1)) continue;
        const double n1 = count[c] - count[a], n2 = count[b] - count[c];
        const double m1 = ms(a, c), m2 = ms(c, b);
        if (m1 <= 0 || m2 <= 0) continue;
        const double ratio = std::sqrt(std::max(m1, m2) / std::min(m1, m2));
        if (ratio < kChangeRmsRatio) continue;
        const double gain = n * std::log(m) - n1 * std::log(m1) - n2 * std::log(m2);
        if (gain > best_gain) best_gain = gain, best_cut = c;
      }
    }
    if (best_cut == 0) break;
    cuts.insert(std::upper_bound(cuts.begin(), cuts.end(), best_cut), best_cut);
  }
  for (std::size_t s = 0; s + 1 < cuts.size(); ++s) {
    ResidualReport::Segment g;
    g.t0_s = w[cuts[s]].t0_s;
    g.t1_s = w[cuts[s + 1] - 1].t1_s;
    g.rmse_pa = std::sqrt(ms(cuts[s], cuts[s + 1]));
    g.at_floor = g.rmse_pa <= kSegmentFloorRatio * r.noise_sigma_pa;
    if (s > 0) r.change_points_s.push_back(g.t0_s);
    r.segments.push_back(g);
  }
}

// "Where in time", in words, when the error is confined to part of the run: one sentence, or
// empty when the error is everywhere (or nowhere).
std::string confinement_sentence(const ResidualReport& r) {
  // Neighbouring segments above the floor are one span here (the level may change inside it).
  std::vector<ResidualReport::Segment> g;
  for (const auto& x : r.segments) {
    if (!g.empty() && !g.back().at_floor && !x.at_floor) {
      const double d0 = g.back().t1_s - g.back().t0_s, d1 = x.t1_s - x.t0_s;
      g.back().rmse_pa = std::sqrt((g.back().rmse_pa * g.back().rmse_pa * d0 + x.rmse_pa * x.rmse_pa * d1) / (d0 + d1));
      g.back().t1_s = x.t1_s;
    } else {
      g.push_back(x);
    }
  }
  if (g.size() < 2) return "";
  // The part at the floor must be a real part of the run (a quarter), not a quiet start.
  double floor_s = 0;
  for (const auto& x : g) floor_s += x.at_floor ? x.t1_s - x.t0_s : 0.0;
  if (floor_s < 0.25 * (g.back().t1_s - g.front().t0_s)) return "";
  std::string spans;
  std::size_t failing = 0;
  for (const auto& x : g) {
    if (x.at_floor) continue;
    ++failing;
    spans += (spans.empty() ? "" : ", ") + text::instant(x.t0_s) + "-" + text::instant(x.t1_s) + " s";
  }
  const double kpa = units::kPaPerKpa;
  const bool first_bad = !g.front().at_floor, last_bad = !g.back().at_floor;
  if (failing == 1 && !first_bad && !last_bad) {
    const ResidualReport::Segment* bad = nullptr;
    for (const auto& x : g)
      if (!x.at_floor) bad = &x;
    return "The error is confined to " + text::instant(bad->t0_s) + "-" + text::instant(bad->t1_s) + " s" +
           fmt(" (RMS %.3g kPa there); before and after it is at the noise floor: something changed at ", bad->rmse_pa / kpa) +
           text::instant(bad->t0_s) + " s and recovered at " + text::instant(bad->t1_s) + " s.";
  }
  if (failing == 1 && last_bad) {
    return "The error starts at " + text::instant(g.back().t0_s) +
           fmt(" s (RMS %.3g kPa after it); before it the model is at the noise floor: something changed at ",
               g.back().rmse_pa / kpa) +
           text::instant(g.back().t0_s) + " s and did not recover before the end of the file.";
  }
  if (failing == 1 && first_bad) {
    return "The error is confined to the start of the run, up to " + text::instant(g.front().t1_s) +
           fmt(" s (RMS %.3g kPa); after it the model is at the noise floor.", g.front().rmse_pa / kpa);
  }
  return "The error comes and goes: above the noise in " + spans + "; at the noise floor in between.";
}

}  // namespace

void ResidualAnalyzer::Impl::describe(ResidualReport& r) {
  auto& out = r.signature;
  const double kpa = units::kPaPerKpa;
  const double rmse = r.error.rmse_pa, sigma = r.noise_sigma_pa;
  if (r.rows == 0) return;
  if (at_noise_floor(rmse, sigma)) {
    out.push_back(fmt("At the noise floor: RMS error %.3g kPa against measurement noise %.3g kPa.", rmse / kpa, sigma / kpa));
  } else {
    out.push_back(
        fmt("RMS error %.3g kPa is %.3g times the measurement noise (%.3g kPa).", rmse / kpa, rmse / sigma, sigma / kpa));
  }
  // A filtered transducer's noise is correlated over a few rows by itself: say so, so that a short
  // residual correlation time is read as the noise's, not as a missing effect.
  if (r.noise.coloured()) {
    const double tau_ms = r.noise.correlation_time_samples() * r.diagnostics.dt_s * 1e3;
    std::string corner = r.noise.corner_hz() > 0 ? fmt(", corner %.3g Hz: an anti-alias filter?", r.noise.corner_hz()) : "";
    out.push_back(
        fmt("The measurement noise is coloured: %.3g kPa of first-order noise (pole %.3g per row",
            r.noise.coloured_sigma_pa / kpa, r.noise.phi) +
        corner +
        fmt(") and %.3g kPa white; by itself it keeps the residual correlated for about ", r.noise.white_sigma_pa / kpa) +
        fmt("%.3g ms.", tau_ms));
  }
  if (std::abs(r.error.bias_pa) > 0.5 * rmse && rmse > 1.5 * sigma) {
    out.push_back(
        fmt("Mostly a constant offset: bias %+.3g kPa (measured above the model when positive).", r.error.bias_pa / kpa));
  }
  // Regimes: the one where the error is largest relative to the whole.
  const Regime* worst = nullptr;
  for (const auto& g : r.regimes) {
    if (g.share < 0.02 || g.error.samples < 20) continue;
    if (worst == nullptr || g.error.rmse_pa > worst->error.rmse_pa) worst = &g;
  }
  auto find = [&](const char* name) -> const Regime* {
    for (const auto& g : r.regimes)
      if (g.name == name) return &g;
    return nullptr;
  };
  const std::string confined = rmse > 1.5 * sigma ? confinement_sentence(r) : "";
  if (!confined.empty()) {
    // Regime shares over the whole run would mislead when the error lives in one span of it.
    out.push_back(confined);
  } else if (worst != nullptr && worst->error.rmse_pa > 1.3 * rmse && rmse > 1.5 * sigma) {
    char b[300];
    std::snprintf(b, sizeof b, "Largest in regime '%s' (%s): RMS %.3g kPa against %.3g kPa overall.", worst->name.c_str(),
                  worst->description.c_str(), worst->error.rmse_pa / kpa, rmse / kpa);
    out.push_back(b);
  } else if (rmse > 1.5 * sigma) {
    out.push_back("Spread evenly over the motion and pressure regimes (no regime's RMS is 1.3x the overall).");
  }
  const Regime *early = find("early"), *late = find("late");
  if (early && late && rmse > 1.5 * sigma && early->error.samples && late->error.samples) {
    const double ratio = late->error.rmse_pa / std::max(early->error.rmse_pa, 1.0);
    if (ratio > 1.5)
      out.push_back(fmt("Grows over the run: RMS %.3g kPa in the first half, %.3g kPa in the second (a drift).",
                        early->error.rmse_pa / kpa, late->error.rmse_pa / kpa));
    else if (ratio < 1 / 1.5)
      out.push_back(fmt("Shrinks over the run: RMS %.3g kPa in the first half, %.3g kPa in the second.",
                        early->error.rmse_pa / kpa, late->error.rmse_pa / kpa));
  }
  const Diagnostics& d = r.diagnostics;
  for (const auto& pk : d.peaks) {
    if (pk.power_share < 0.05) continue;
    out.push_back(fmt("Spectrum: %.0f %% of the residual power in a peak at %.3g Hz", 100 * pk.power_share, pk.hz) + ": " +
                  pk.name + ".");
  }
  if (rmse > 1.5 * sigma && d.angle_ripple_period_deg > 0) {
    out.push_back(
        fmt("Periodic in the drive angle (the encoder's, or the command's without one): a ripple of %.3g kPa with a "
            "%.3g deg period (%.0f %% of the residual's variation with the angle once slower trends are removed): a "
            "gear or coupling error (one period per tooth or per turn)? No candidate holds it: write it as an effect.",
            d.angle_ripple_kpa, d.angle_ripple_period_deg, 100 * d.angle_ripple_share));
  }
  if (rmse > 1.5 * sigma && d.low_frequency_share > 0.5) {
    out.push_back(fmt("Slow: %.0f %% of the residual power lies below 0.5 Hz (static or slowly varying error).",
                      100 * d.low_frequency_share));
  }
  if (d.white) {
    out.push_back("Residual is white (autocorrelation inside the 99 % bounds).");
  } else {
    out.push_back(fmt("Residual is correlated: %.0f %% of lags outside the 99 %% bounds, correlation time %.3g s.",
                      100 * d.acf_outside_share, d.tau_int_samples * d.dt_s));
  }
  if (!d.xcf.empty()) {
    if (d.input_correlated) {
      // Which leads says something only for a clear correlation that no periodic peak dominates
      // (two signals oscillating together correlate at every lag).
      bool periodic = false;
      for (const auto& pk : d.peaks) periodic |= pk.power_share > 0.3;
      std::string why = ".";
      if (d.xcf_max_abs >= 0.2 && !periodic) {
        why = d.xcf_max_lag_s < 0 ? ": the drive follows the residual (the controller reacting to what the model lacks)."
                                  : ": the residual follows the drive (the model answers the drive's motion wrongly).";
      }
      out.push_back(fmt("Correlated with the drive motion: peak cross-correlation %.2f at lag %+.0f ms (bound %.2g)",
                        d.xcf_max_abs, 1e3 * d.xcf_max_lag_s, d.xcf_bound) +
                    why);
    } else {
      out.push_back("Not correlated with the drive motion (cross-correlation inside the 99 % bounds).");
    }
  }
}

}  // namespace hil::analysis
