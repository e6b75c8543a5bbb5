// The residual analyser's state and helpers, internal to residuals*.cpp: residuals.cpp streams
// the rows and finishes the metrics, regimes and windows; residual_diagnostics.cpp the
// correlations, whiteness and spectrum; residual_words.cpp where in time the error lives and the
// signature in words.
#pragma once

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
#include "velocity_signature.hpp"
#include "fft.hpp"
#include "hil/minmax_decimator.hpp"
#include "hil/units.hpp"

#include "text.hpp"
#include "hil/analysis/residuals.hpp"

namespace hil::analysis {
namespace residual_detail {

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

inline std::string fmt(const char* f, double a) {
  char b[512];
  std::snprintf(b, sizeof b, f, a);
  return b;
}
inline std::string fmt(const char* f, double a, double b2) {
  char b[512];
  std::snprintf(b, sizeof b, f, a, b2);
  return b;
}
inline std::string fmt(const char* f, double a, double b2, double c) {
  char b[512];
  std::snprintf(b, sizeof b, f, a, b2, c);
  return b;
}

// tau_int = 1 + 2 sum rho(l), truncated by Geyer's initial positive sequence.
double tau_from_acf(const std::vector<double>& rho);
// Change points of the residual's level (residual_words.cpp).
void find_segments(ResidualReport& r);

}  // namespace residual_detail

using namespace residual_detail;

struct ResidualAnalyzer::Impl {
  detail::AngleProfile angle;        // the residual against the drive angle
  detail::VelocityProfile velocity;  // and against its velocity
  double drive_velocity_rad_s = 0;   // over the last ~10 ms (classify_motion)
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
    drive_velocity_rad_s = v;
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
    velocity.add(units::rad_to_deg(drive_velocity_rad_s), e);
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

}  // namespace hil::analysis
